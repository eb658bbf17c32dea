#include "ffloc/io/json_fields.h"

#include <algorithm>
#include <cmath>
#include <cstdint>
#include <fstream>
#include <iterator>
#include <limits>
#include <string>
#include <vector>

#include "ffloc/core/error.h"
#include "ffloc/io/input_file.h"

namespace ffloc {

using nlohmann::json;

namespace {

// Walks a JSON text's events, building nothing, for a key that an object gives twice. The parser
// with a callback could see the keys too, but it rescans an array's elements each time one of
// them ends: 17 MB of manifest took 1.4 s instead of 0.13 s.
class DuplicateKeyFinder : public nlohmann::json_sax<json> {
 public:
  // The first duplicated key's path, as JsonFields names fields ("frames[2].camera"); empty when
  // every object's keys differ.
  const std::string& duplicate() const { return duplicate_; }

  bool null() override { return value(); }
  bool boolean(bool) override { return value(); }
  bool number_integer(number_integer_t) override { return value(); }
  bool number_unsigned(number_unsigned_t) override { return value(); }
  bool number_float(number_float_t, const string_t&) override { return value(); }
  bool string(string_t&) override { return value(); }
  bool binary(binary_t&) override { return value(); }
  bool start_object(std::size_t) override { return open(false); }
  bool start_array(std::size_t) override { return open(true); }
  bool key(string_t& name) override {
    Container& object = containers_[depth_ - 1];
    object.key = name;
    object.keys.push_back(name);
    return true;
  }
  bool end_object() override {
    std::vector<std::string>& keys = containers_[depth_ - 1].keys;
    std::sort(keys.begin(), keys.end());
    const auto twice = std::adjacent_find(keys.begin(), keys.end());
    if (twice != keys.end()) {
      containers_[depth_ - 1].key = *twice;
      duplicate_ = path();
      return false;
    }
    --depth_;
    return value();
  }
  bool end_array() override {
    --depth_;
    return value();
  }
  bool parse_error(std::size_t, const std::string&, const json::exception&) override { return false; }

 private:
  // An open object or array; kept when closed, so that the next one reuses its memory.
  struct Container {
    bool array = false;
    size_t elements = 0;            // of an array, so far
    std::string key;                // of an object, the one whose value is being read
    std::vector<std::string> keys;  // of an object, so far
  };

  bool open(bool array) {
    if (depth_ == containers_.size()) containers_.emplace_back();
    Container& container = containers_[depth_++];
    container.array = array;
    container.elements = 0;
    container.keys.clear();
    return true;
  }

  bool value() {
    if (depth_ > 0 && containers_[depth_ - 1].array) ++containers_[depth_ - 1].elements;
    return true;
  }

  // The path of the value being read, through every open container.
  std::string path() const {
    std::string text;
    for (size_t i = 0; i < depth_; ++i) {
      const Container& container = containers_[i];
      if (container.array) {
        text += "[" + std::to_string(container.elements) + "]";
      } else {
        text += (text.empty() ? "" : ".") + container.key;
      }
    }
    return text;
  }

  std::vector<Container> containers_;
  size_t depth_ = 0;
  std::string duplicate_;
};

// nlohmann's message without its tag: "[json.exception.parse_error.101] parse error at ..." named
// the library's exception to a user who had given a file.
std::string untagged(const json::exception& error) {
  const std::string what = error.what();
  const size_t end = what.rfind("[json.exception.", 0) == 0 ? what.find("] ") : std::string::npos;
  return end == std::string::npos ? what : what.substr(end + 2);
}

}  // namespace

json parseJson(const std::string& text, const std::string& source) {
  json parsed;
  try {
    parsed = json::parse(text);
  } catch (const json::parse_error& e) {
    // Python's json module writes NaN and Infinity, which JSON does not have; say so, since the
    // parser only says "invalid literal".
    const size_t at = e.byte >= 2 ? e.byte - 2 : 0;
    const std::string near = text.substr(std::min(at, text.size()), 10);
    const bool non_finite = near.find("NaN") != std::string::npos || near.find("Infinity") != std::string::npos;
    throwInputError(source, 0,
                    "invalid JSON: " + untagged(e) +
                        (non_finite ? " (NaN and Infinity are not JSON; write finite numbers or null)" : ""));
  } catch (const json::exception& e) {
    throwInputError(source, 0, "invalid JSON: " + untagged(e));
  }
  DuplicateKeyFinder finder;
  json::sax_parse(text, &finder);
  if (!finder.duplicate().empty()) throwInputError(source, 0, "field '" + finder.duplicate() + "': duplicated key");
  return parsed;
}

json parseJsonFile(const std::filesystem::path& file) {
  requireRegularFile(file);
  std::ifstream in(file, std::ios::binary);
  if (!in) throwInputError(file.string(), 0, "cannot open file");
  return parseJson({std::istreambuf_iterator<char>(in), std::istreambuf_iterator<char>()}, file.string());
}

json matrix4Json(const Eigen::Matrix4d& T) {
  json rows = json::array();
  for (int r = 0; r < 4; ++r) rows.push_back({T(r, 0), T(r, 1), T(r, 2), T(r, 3)});
  return rows;
}

JsonFields::JsonFields(const json& object, std::filesystem::path file, std::string path)
    : object_(object), file_(std::move(file)), path_(std::move(path)) {
  if (!object_.is_object()) fail("", "expected a JSON object");
}

bool JsonFields::has(const std::string& key) const { return object_.contains(key) && !object_.at(key).is_null(); }

std::string JsonFields::field(const std::string& key) const { return path_.empty() ? key : path_ + "." + key; }

const json& JsonFields::get(const std::string& key) const {
  if (!has(key)) fail(key, "missing field");
  return object_.at(key);
}

double JsonFields::number(const std::string& key) const {
  const json& value = get(key);
  if (!value.is_number()) fail(key, "expected a number");
  return value.get<double>();
}

double JsonFields::finiteNumber(const std::string& key) const {
  const double value = number(key);
  if (!std::isfinite(value)) fail(key, "expected a finite number");
  return value;
}

int64_t JsonFields::integer(const std::string& key, int64_t lo, int64_t hi) const {
  const json& value = get(key);
  const bool in_range = value.is_number_integer() &&
                        !(value.is_number_unsigned() && value.get<uint64_t>() > static_cast<uint64_t>(INT64_MAX)) &&
                        value.get<int64_t>() >= lo && value.get<int64_t>() <= hi;
  if (!in_range) {
    // 640.0 was told "expected an integer in [..]", though 640 is in the range.
    const std::string written_as = value.is_number_float() ? " (written " + value.dump() + ": drop the decimal point)" : "";
    fail(key, "expected an integer in [" + std::to_string(lo) + ", " + std::to_string(hi) + "]" + written_as);
  }
  return value.get<int64_t>();
}

int JsonFields::integer(const std::string& key) const {
  return static_cast<int>(integer(key, std::numeric_limits<int>::min(), std::numeric_limits<int>::max()));
}

bool JsonFields::boolean(const std::string& key) const {
  const json& value = get(key);
  if (!value.is_boolean()) fail(key, "expected true or false");
  return value.get<bool>();
}

std::string JsonFields::string(const std::string& key) const {
  const json& value = get(key);
  if (!value.is_string()) fail(key, "expected a string");
  return value.get<std::string>();
}

std::vector<double> JsonFields::numbers(const std::string& key) const {
  const json& value = get(key);
  if (!value.is_array()) fail(key, "expected an array of numbers");
  std::vector<double> out;
  for (const auto& item : value) {
    if (!item.is_number()) fail(key, "expected an array of numbers");
    out.push_back(item.get<double>());
  }
  return out;
}

Eigen::Matrix4d JsonFields::matrix4(const std::string& key) const {
  const json& rows = get(key);
  const char* expected = "expected a 4x4 matrix (4 rows of 4 numbers)";
  if (!rows.is_array() || rows.size() != 4) fail(key, expected);
  Eigen::Matrix4d T;
  for (int r = 0; r < 4; ++r) {
    if (!rows[r].is_array() || rows[r].size() != 4) fail(key, expected);
    for (int c = 0; c < 4; ++c) {
      if (!rows[r][c].is_number()) fail(key, expected);
      T(r, c) = rows[r][c].get<double>();
    }
  }
  return T;
}

void JsonFields::requireKnownKeys(const std::vector<std::string>& known) const {
  if (!object_.is_object()) return;
  for (const auto& item : object_.items()) {
    if (std::find(known.begin(), known.end(), item.key()) != known.end()) continue;
    std::string list;
    for (const std::string& key : known) list += (list.empty() ? "" : ", ") + key;
    fail(item.key(), "unknown field (known here: " + list + ")");
  }
}

void JsonFields::fail(const std::string& key, const std::string& what) const {
  const std::string name = key.empty() ? path_ : field(key);
  throwInputError(file_.string(), 0, (name.empty() ? "" : "field '" + name + "': ") + what);
}

}  // namespace ffloc
