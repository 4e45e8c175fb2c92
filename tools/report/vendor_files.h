// The vendored browser library of the report's interactive plots, embedded in the program at build
// time (tools/report/embed_files.cmake writes the definitions from the files in
// tools/report/vendor/): dygraphs 2.2.1, MIT (tools/report/vendor/dygraphs/README.md says where the
// files come from, with their hashes). The bytes are the files' own, unchanged.
#pragma once

#include <string_view>

namespace mjsysid::report {

std::string_view DygraphJs();   // dygraph.min.js
std::string_view DygraphCss();  // dygraph.min.css

}  // namespace mjsysid::report
