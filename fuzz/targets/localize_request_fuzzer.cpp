// The server's decoding of POST /localize: the input's first piece holds the form fields, one
// "name=value" a line, and everything after the first NUL is the image's bytes.
#include "../support/fuzz_support.h"
#include "ffloc/server/localize_request.h"

using namespace ffloc;

extern "C" int LLVMFuzzerTestOneInput(const uint8_t* data, size_t size) {
  const std::string_view input(reinterpret_cast<const char*>(data), size);
  const size_t end_of_fields = input.find('\0');
  const std::string_view field_text = input.substr(0, end_of_fields);
  const std::string image = end_of_fields == std::string_view::npos ? "" : std::string(input.substr(end_of_fields + 1));
  std::map<std::string, std::string> fields;
  size_t begin = 0;
  while (begin <= field_text.size()) {
    const size_t line_end = std::min(field_text.find('\n', begin), field_text.size());
    const std::string_view line = field_text.substr(begin, line_end - begin);
    const size_t equals = line.find('=');
    if (equals != std::string_view::npos) fields[std::string(line.substr(0, equals))] = std::string(line.substr(equals + 1));
    begin = line_end + 1;
  }
  fuzz::expectOnlyInputErrors([&] { parseLocalizeRequest(fields, image, LocalizeOptions{}); });
  return 0;
}
