#include "ffloc/io/json_fields.h"

#include <algorithm>
#include <cmath>
#include <cstdint>
#include <fstream>
#include <iterator>
#include <limits>

#include "ffloc/core/error.h"
#include "ffloc/io/input_file.h"

namespace ffloc {

using nlohmann::json;

json parseJsonFile(const std::filesystem::path& file) {
  requireRegularFile(file);
  std::ifstream in(file, std::ios::binary);
  if (!in) throwInputError(file.string(), 0, "cannot open file");
  const std::string text{std::istreambuf_iterator<char>(in), std::istreambuf_iterator<char>()};
  try {
    return json::parse(text);
  } catch (const json::parse_error& e) {
    // Python's json module writes NaN and Infinity, which JSON does not have; say so, since the
    // parser only says "invalid literal".
    const size_t at = e.byte >= 2 ? e.byte - 2 : 0;
    const std::string near = text.substr(std::min(at, text.size()), 10);
    const bool non_finite = near.find("NaN") != std::string::npos || near.find("Infinity") != std::string::npos;
    throwInputError(file.string(), 0,
                    std::string("invalid JSON: ") + e.what() +
                        (non_finite ? " (NaN and Infinity are not JSON; write finite numbers or null)" : ""));
  } catch (const json::exception& e) {
    throwInputError(file.string(), 0, std::string("invalid JSON: ") + e.what());
  }
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
  if (!in_range) fail(key, "expected an integer in [" + std::to_string(lo) + ", " + std::to_string(hi) + "]");
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
