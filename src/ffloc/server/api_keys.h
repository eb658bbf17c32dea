#pragma once

#include <filesystem>
#include <set>
#include <string>
#include <vector>

namespace ffloc {

// Who may use which map (ffloc serve --keys FILE). The file holds one key a line followed by the
// maps it may use, comma-separated, or `*` for every map; blank lines and lines starting with '#'
// are skipped:
//   3f9c1d0e8a7b4c2d9e6f  kitchen,office
//   a81e2f6c0b9d4e7f3a5c  *
// Clients send `Authorization: Bearer <key>`.
class ApiKeys {
 public:
  enum class Decision { kAllowed, kUnauthenticated, kForbidden };

  // InputError naming the file and line for a malformed line, a key given twice, a key shorter
  // than kMinimumKeyLength, or a map that `known_maps` does not hold.
  static ApiKeys read(const std::filesystem::path& file, const std::vector<std::string>& known_maps);

  // The key in an Authorization header value ("Bearer <key>"); kUnauthenticated when it is missing
  // or not a key of the file, kForbidden when the key may not use `map` (an empty `map`: any map
  // is enough, as for listing). Every key is compared in full, in time that does not depend on
  // where a guess differs.
  Decision decide(const std::string& authorization, const std::string& map) const;
  // The maps the key in `authorization` may use, of `maps` (none for an unknown key).
  std::vector<std::string> allowedMaps(const std::string& authorization, const std::vector<std::string>& maps) const;

  static constexpr size_t kMinimumKeyLength = 16;

 private:
  struct Grant {
    std::string key;
    bool every_map = false;
    std::set<std::string> maps;
  };
  const Grant* find(const std::string& authorization) const;

  std::vector<Grant> grants_;
};

}  // namespace ffloc
