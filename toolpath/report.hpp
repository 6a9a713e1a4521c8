// What toolpath tells a person: a one-paragraph summary and the gouge list for stderr, and the
// --report JSON (keys documented in docs/toolpath.md).
#pragma once

#include <cstddef>
#include <ostream>
#include <string>
#include <vector>

#include "toolpath/part.hpp"
#include "toolpath/toolpath.hpp"
#include "toolpath/uncertain_stock.hpp"
#include "toolpath/zmap.hpp"

namespace photomill::toolpath {

struct ReportContext {
  std::string input;                 // the input's name as given
  std::size_t face = 0;              // face used (0 for a photomill surface)
  std::size_t faces = 1;             // faces in the input
  const ToolpathOptions* options = nullptr;
  const ToolpathResult* result = nullptr;
  const ZmapResult* verify = nullptr;  // null unless --verify
  std::string direction;             // "u" or "v"
  std::string pattern;               // "zigzag" or "oneway"
  const UncertainStockStats* stock = nullptr;  // null unless --stock-uncertainty
  std::string stock_file;            // --stock-uncertainty's file
};

void write_report(std::ostream& out, const ReportContext& context);

// --all-faces: the whole part's report (keys in docs/toolpath.md): options, every face with what
// became of it, the whole-part check, the z-map (null without --verify).
void write_part_report(std::ostream& out, const std::string& input, const ToolpathOptions& options,
                       const PartToolpathResult& result, double mesh_tol_mm, std::size_t mesh_triangles,
                       const PartZmapResult* verify);

// Lines for stderr: the summary, up to `max_gouges` gouge runs ("... and N more"), the z-map.
std::vector<std::string> summary_lines(const ReportContext& context, std::size_t max_gouges = 10);

}  // namespace photomill::toolpath
