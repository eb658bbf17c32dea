#pragma once

#include <Eigen/Core>
#include <filesystem>
#include <nlohmann/json.hpp>
#include <string>
#include <vector>

// Typed access to the fields of a JSON object for the JSON readers (manifest, transforms.json).
// Every failure is an InputError "<file>: field '<path>.<key>': <what>".
namespace ffloc {

// `text` as JSON; InputError naming `source` when it is not JSON or an object gives a key twice
// ("field 'frames[2].camera': duplicated key"): nlohmann keeps the last of the two silently, so
// {"steps": 10, "steps": 20} trained 20 steps without a word.
nlohmann::json parseJson(const std::string& text, const std::string& source);
// parseJson of a file's text, once requireRegularFile accepts the file.
nlohmann::json parseJsonFile(const std::filesystem::path& file);

// 4 rows of 4 numbers: what JsonFields::matrix4 reads back.
nlohmann::json matrix4Json(const Eigen::Matrix4d& T);

class JsonFields {
 public:
  // `path` names the object inside the file ("frames[3]"); empty for the top level.
  JsonFields(const nlohmann::json& object, std::filesystem::path file, std::string path);

  bool has(const std::string& key) const;  // present and not null
  std::string field(const std::string& key) const;

  const nlohmann::json& get(const std::string& key) const;
  double number(const std::string& key) const;
  double finiteNumber(const std::string& key) const;  // JSON's 1e999 parses as infinity
  int integer(const std::string& key) const;  // one that fits an int
  // An integer within [lo, hi], checked before any narrowing.
  int64_t integer(const std::string& key, int64_t lo, int64_t hi) const;
  bool boolean(const std::string& key) const;
  std::string string(const std::string& key) const;
  std::vector<double> numbers(const std::string& key) const;
  Eigen::Matrix4d matrix4(const std::string& key) const;  // 4 rows of 4 numbers

  [[noreturn]] void fail(const std::string& key, const std::string& what) const;

  // Fails on the first key of the object that is not one of `known`: a misspelt or invented field
  // (a camera's "k1" meant as distortion) was read as absent, without a word.
  void requireKnownKeys(const std::vector<std::string>& known) const;

 private:
  const nlohmann::json& object_;
  std::filesystem::path file_;
  std::string path_;
};

}  // namespace ffloc
