// PDF and SVG writers for the target sheets (see render.hpp).
#include "targets/render.hpp"

#include <charconv>
#include <cmath>
#include <cstdio>
#include <ostream>
#include <stdexcept>
#include <string>
#include <vector>

namespace photomill::targets {
namespace {

// Fixed-point with at most 4 decimals (0.1 um in mm), trailing zeros dropped; locale-free.
std::string num(double v) {
  if (!std::isfinite(v)) throw std::invalid_argument("targets: a sheet coordinate is not finite");
  if (std::abs(v) < 5e-5) v = 0;
  char buf[64];
  const auto r = std::to_chars(buf, buf + sizeof buf, v, std::chars_format::fixed, 4);
  std::string s(buf, r.ptr);
  while (!s.empty() && s.back() == '0') s.pop_back();
  if (!s.empty() && s.back() == '.') s.pop_back();
  return s == "-0" ? "0" : s;
}

std::string printable(const std::string& text) {
  std::string out;
  for (char c : text) out += (c >= 32 && c < 127) ? c : '?';
  return out;
}

// A PDF literal string: backslash, parentheses escaped (PDF 1.4 reference, 3.2.3).
std::string pdf_string(const std::string& text) {
  std::string out = "(";
  for (char c : printable(text)) {
    if (c == '\\' || c == '(' || c == ')') out += '\\';
    out += c;
  }
  return out + ")";
}

std::string xml_escape(const std::string& text) {
  std::string out;
  for (char c : printable(text)) {
    switch (c) {
      case '&': out += "&amp;"; break;
      case '<': out += "&lt;"; break;
      case '>': out += "&gt;"; break;
      case '"': out += "&quot;"; break;
      default: out += c;
    }
  }
  return out;
}

// 1 mm in PDF units (1/72 inch).
constexpr double kPointsPerMm = 72.0 / 25.4;

}  // namespace

void write_pdf(std::ostream& out, const Sheet& sheet) {
  std::string content;
  content += "q\n";
  {
    char scale[64];
    const auto r = std::to_chars(scale, scale + sizeof scale, kPointsPerMm, std::chars_format::fixed, 10);
    const std::string k(scale, r.ptr);
    content += k + " 0 0 " + k + " 0 0 cm\n";  // user space in mm from here on
  }
  if (!sheet.black.empty()) {
    content += "0 g\n";
    for (const auto& b : sheet.black) content += num(b.x_mm) + " " + num(b.y_mm) + " " + num(b.w_mm) + " " + num(b.h_mm) + " re\n";
    content += "f\n";
  }
  content += "0 J\n";
  for (const auto& l : sheet.lines) {
    content += num(l.grey) + " G " + num(l.width_mm) + " w " + num(l.a_mm.x()) + " " + num(l.a_mm.y()) + " m " +
               num(l.b_mm.x()) + " " + num(l.b_mm.y()) + " l S\n";
  }
  if (!sheet.texts.empty()) {
    content += "0 g\n";
    for (const auto& t : sheet.texts) {
      content += "BT /F1 " + num(t.size_mm) + " Tf " + num(t.x_mm) + " " + num(t.y_mm) + " Td " + pdf_string(t.text) +
                 " Tj ET\n";
    }
  }
  content += "Q\n";

  const std::string w = num(sheet.width_mm * kPointsPerMm), h = num(sheet.height_mm * kPointsPerMm);
  std::vector<std::string> objects{
      "<< /Type /Catalog /Pages 2 0 R >>",
      "<< /Type /Pages /Kids [3 0 R] /Count 1 >>",
      "<< /Type /Page /Parent 2 0 R /MediaBox [0 0 " + w + " " + h + "] /CropBox [0 0 " + w + " " + h +
          "] /Resources << /Font << /F1 5 0 R >> >> /Contents 4 0 R >>",
      "<< /Length " + std::to_string(content.size()) + " >>\nstream\n" + content + "endstream",
      "<< /Type /Font /Subtype /Type1 /BaseFont /Courier /Encoding /WinAnsiEncoding >>",
      "<< /Title " + pdf_string(sheet.title) + " /Creator (photomill targets) /Producer (photomill) >>"};
  std::string pdf = "%PDF-1.4\n%\xE2\xE3\xCF\xD3\n";
  std::vector<std::size_t> offsets;
  for (std::size_t i = 0; i < objects.size(); ++i) {
    offsets.push_back(pdf.size());
    pdf += std::to_string(i + 1) + " 0 obj\n" + objects[i] + "\nendobj\n";
  }
  const std::size_t xref = pdf.size();
  pdf += "xref\n0 " + std::to_string(objects.size() + 1) + "\n0000000000 65535 f \n";
  for (const auto o : offsets) {
    char line[32];
    std::snprintf(line, sizeof line, "%010zu 00000 n \n", o);
    pdf += line;
  }
  pdf += "trailer\n<< /Size " + std::to_string(objects.size() + 1) + " /Root 1 0 R /Info 6 0 R >>\nstartxref\n" +
         std::to_string(xref) + "\n%%EOF\n";
  out.write(pdf.data(), static_cast<std::streamsize>(pdf.size()));
}

void write_svg(std::ostream& out, const Sheet& sheet) {
  const double H = sheet.height_mm;
  out << "<?xml version=\"1.0\" encoding=\"UTF-8\"?>\n"
      << "<svg xmlns=\"http://www.w3.org/2000/svg\" version=\"1.1\" width=\"" << num(sheet.width_mm) << "mm\" height=\""
      << num(H) << "mm\" viewBox=\"0 0 " << num(sheet.width_mm) << " " << num(H) << "\">\n"
      << "<title>" << xml_escape(sheet.title) << "</title>\n"
      << "<rect x=\"0\" y=\"0\" width=\"" << num(sheet.width_mm) << "\" height=\"" << num(H) << "\" fill=\"#ffffff\"/>\n";
  if (!sheet.black.empty()) {
    // SVG's y runs down: a rectangle's top-left is (x, H - y - h); every subpath clockwise on the
    // page, so the non-zero rule fills their union.
    out << "<path fill=\"#000000\" fill-rule=\"nonzero\" d=\"";
    for (const auto& b : sheet.black) {
      out << "M" << num(b.x_mm) << " " << num(H - b.y_mm - b.h_mm) << "h" << num(b.w_mm) << "v" << num(b.h_mm) << "h"
          << num(-b.w_mm) << "z";
    }
    out << "\"/>\n";
  }
  for (const auto& l : sheet.lines) {
    const int g = static_cast<int>(std::lround(255 * l.grey));
    out << "<line x1=\"" << num(l.a_mm.x()) << "\" y1=\"" << num(H - l.a_mm.y()) << "\" x2=\"" << num(l.b_mm.x())
        << "\" y2=\"" << num(H - l.b_mm.y()) << "\" stroke=\"rgb(" << g << "," << g << "," << g << ")\" stroke-width=\""
        << num(l.width_mm) << "\"/>\n";
  }
  for (const auto& t : sheet.texts) {
    out << "<text x=\"" << num(t.x_mm) << "\" y=\"" << num(H - t.y_mm) << "\" font-family=\"Courier, 'Courier New', monospace\" font-size=\""
        << num(t.size_mm) << "\" fill=\"#000000\" xml:space=\"preserve\">" << xml_escape(t.text) << "</text>\n";
  }
  out << "</svg>\n";
}

}  // namespace photomill::targets
