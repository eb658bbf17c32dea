#include "ffloc/server/api_keys.h"

#include <algorithm>
#include <fstream>
#include <sstream>

#include "ffloc/core/error.h"
#include "ffloc/core/utf8.h"

namespace ffloc {

namespace {

// Equal without stopping at the first difference: the time depends on the lengths only.
bool equalInConstantTime(const std::string& a, const std::string& b) {
  const size_t length = std::max(a.size(), b.size());
  unsigned difference = a.size() == b.size() ? 0u : 1u;
  for (size_t i = 0; i < length; ++i) {
    const unsigned char x = i < a.size() ? static_cast<unsigned char>(a[i]) : 0;
    const unsigned char y = i < b.size() ? static_cast<unsigned char>(b[i]) : 0;
    difference |= static_cast<unsigned>(x ^ y);
  }
  return difference == 0;
}

std::string bearerToken(const std::string& authorization) {
  const std::string scheme = "Bearer ";
  if (authorization.size() <= scheme.size()) return "";
  if (asciiLowercase(authorization.substr(0, scheme.size())) != "bearer ") return "";
  std::string token = authorization.substr(scheme.size());
  const size_t first = token.find_first_not_of(' ');
  return first == std::string::npos ? "" : token.substr(first);
}

}  // namespace

ApiKeys ApiKeys::read(const std::filesystem::path& file, const std::vector<std::string>& known_maps) {
  std::error_code error;
  if (!std::filesystem::is_regular_file(file, error)) throwInputError(file.string(), 0, "not a readable file of keys");
  std::ifstream in(file);
  if (!in) throwInputError(file.string(), 0, "cannot read the file of keys");
  ApiKeys keys;
  std::string line;
  for (int number = 1; std::getline(in, line); ++number) {
    if (!line.empty() && line.back() == '\r') line.pop_back();
    // Kept, a byte order mark became part of the first key, which then never matched.
    if (number == 1 && line.rfind("\xEF\xBB\xBF", 0) == 0) line.erase(0, 3);
    std::istringstream words(line);
    std::string key, maps, extra;
    if (!(words >> key) || key[0] == '#') continue;
    // '#' starts a comment at the end of a line too, as the docs said (it was refused there).
    if (!(words >> maps) || ((words >> extra) && extra[0] != '#')) {
      throwInputError(file.string(), number, "expected '<key> <map>[,<map>...]' or '<key> *'");
    }
    // A key travels in an HTTP header: one with a control or non-ASCII byte can never be sent.
    if (!std::all_of(key.begin(), key.end(), [](unsigned char c) { return c > 0x20 && c < 0x7F; }))
      throwInputError(file.string(), number, "a key may hold only printable ASCII characters");
    if (maps.back() == ',' || maps.find(",,") != std::string::npos)
      throwInputError(file.string(), number, "an empty map name in '" + maps + "'");
    if (key.size() < kMinimumKeyLength) {
      throwInputError(file.string(), number, "key shorter than " + std::to_string(kMinimumKeyLength) + " characters");
    }
    for (const Grant& grant : keys.grants_) {
      if (grant.key == key) throwInputError(file.string(), number, "key given twice");
    }
    Grant grant;
    grant.key = key;
    if (maps == "*") {
      grant.every_map = true;
    } else {
      std::istringstream names(maps);
      std::string name;
      while (std::getline(names, name, ',')) {
        if (std::find(known_maps.begin(), known_maps.end(), name) == known_maps.end()) {
          throwInputError(file.string(), number, "map '" + name + "' is not one this server serves");
        }
        grant.maps.insert(name);
      }
    }
    keys.grants_.push_back(std::move(grant));
  }
  if (keys.grants_.empty()) throwInputError(file.string(), 0, "holds no key");
  return keys;
}

const ApiKeys::Grant* ApiKeys::find(const std::string& authorization) const {
  const std::string token = bearerToken(authorization);
  const Grant* found = nullptr;
  // Every key is compared, whichever matches, so the time says nothing about which one did.
  for (const Grant& grant : grants_) {
    if (equalInConstantTime(grant.key, token) && !token.empty()) found = &grant;
  }
  return found;
}

ApiKeys::Decision ApiKeys::decide(const std::string& authorization, const std::string& map) const {
  const Grant* grant = find(authorization);
  if (!grant) return Decision::kUnauthenticated;
  if (map.empty() || grant->every_map || grant->maps.count(map)) return Decision::kAllowed;
  return Decision::kForbidden;
}

std::vector<std::string> ApiKeys::allowedMaps(const std::string& authorization,
                                              const std::vector<std::string>& maps) const {
  const Grant* grant = find(authorization);
  std::vector<std::string> out;
  if (!grant) return out;
  for (const std::string& map : maps) {
    if (grant->every_map || grant->maps.count(map)) out.push_back(map);
  }
  return out;
}

}  // namespace ffloc
