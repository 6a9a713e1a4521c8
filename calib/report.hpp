// calib's outputs besides camera.yaml: the readable report (lines for stderr), the JSON report
// (--report) and the residual plot (--plot: residual vectors over the image frame, PNG).
#pragma once

#include <ostream>
#include <string>
#include <vector>

#include "calib/calibrate.hpp"

namespace photomill::calib {

// The report a person reads: views with their RMS, the camera with standard deviations, the
// optimiser's figures. One string per line, without the program prefix.
std::vector<std::string> text_report(const CalibResult& result);

// One JSON object; keys documented in docs/calib.md.
void write_json_report(std::ostream& out, const CalibResult& result, const CalibOptions& options);

struct ResidualPlot {
  std::vector<unsigned char> png;  // the encoded image
  double magnification = 1;        // residual vectors are drawn this many times their length
  double bar_px = 1;               // the legend bar stands for this residual, in image px
};

// Residual vectors (model - observed, magnified) drawn from each observed point over the image
// frame; rejected views in orange. The magnification is a 1-2-5 step chosen so that the 95th
// percentile residual is drawn about 3 % of the frame diagonal long.
ResidualPlot residual_plot(const CalibResult& result);

}  // namespace photomill::calib
