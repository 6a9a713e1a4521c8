// Open CASCADE glue behind formats/cad.hpp: photomill's BSplineSurface <-> Geom_BSplineSurface,
// one face per surface, STEP/IGES through the XSControl readers and writers. Every entry point
// silences Open CASCADE's messenger (stdout by default), sets the exchange parameters it relies
// on, and turns Standard_Failure into InputError.
#include "formats/cad.hpp"

#include <algorithm>
#include <cctype>
#include <cerrno>
#include <cmath>
#include <csignal>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <functional>
#include <sstream>
#include <string_view>
#include <utility>

#include <pwd.h>
#include <sys/resource.h>
#include <sys/wait.h>
#include <unistd.h>

#include <APIHeaderSection_MakeHeader.hxx>
#include <IGESData_GlobalSection.hxx>
#include <Interface_HArray1OfHAsciiString.hxx>
#include <Standard_Version.hxx>

#include <BRepBuilderAPI_MakeEdge.hxx>
#include <BRepBuilderAPI_MakeFace.hxx>
#include <BRepBuilderAPI_MakeVertex.hxx>
#include <BRepBuilderAPI_MakeWire.hxx>
#include <BRepBuilderAPI_NurbsConvert.hxx>
#include <BRepLib.hxx>
#include <BRepTools.hxx>
#include <BRepTools_WireExplorer.hxx>
#include <BRepMesh_IncrementalMesh.hxx>
#include <BRep_Tool.hxx>
#include <Poly_Triangulation.hxx>
#include <TopLoc_Location.hxx>
#include <Geom2d_BSplineCurve.hxx>
#include <Geom2d_BezierCurve.hxx>
#include <Geom2d_Curve.hxx>
#include <Geom2d_Line.hxx>
#include <Geom2d_TrimmedCurve.hxx>
#include <Geom_BSplineSurface.hxx>
#include <Geom_RectangularTrimmedSurface.hxx>
#include <IFSelect_ReturnStatus.hxx>
#include <IGESControl_Controller.hxx>
#include <IGESControl_Reader.hxx>
#include <IGESControl_Writer.hxx>
#include <IGESData_IGESModel.hxx>
#include <IGESData_IGESWriter.hxx>
#include <IGESSelect_WorkLibrary.hxx>
#include <Interface_Check.hxx>
#include <Interface_CheckIterator.hxx>
#include <Interface_FloatWriter.hxx>
#include <Interface_InterfaceModel.hxx>
#include <Interface_Static.hxx>
#include <Message.hxx>
#include <Message_Messenger.hxx>
#include <Message_Printer.hxx>
#include <Precision.hxx>
#include <STEPControl_Controller.hxx>
#include <STEPControl_Reader.hxx>
#include <STEPControl_Writer.hxx>
#include <Standard_Failure.hxx>
#include <StepData_Protocol.hxx>
#include <StepData_StepModel.hxx>
#include <StepData_StepWriter.hxx>
#include <TColStd_HSequenceOfHAsciiString.hxx>
#include <TCollection_HAsciiString.hxx>
#include <TColStd_Array1OfInteger.hxx>
#include <TColStd_Array1OfReal.hxx>
#include <TColStd_Array2OfReal.hxx>
#include <TColgp_Array2OfPnt.hxx>
#include <TopExp_Explorer.hxx>
#include <TopoDS.hxx>
#include <TopoDS_Face.hxx>
#include <TopoDS_Wire.hxx>
#include <XSControl_WorkSession.hxx>

#include "formats/error.hpp"
#include "formats/log.hpp"

// Present only in sanitizer builds (weak: null otherwise).
extern "C" void __sanitizer_set_death_callback(void (*callback)(void)) __attribute__((weak));

namespace photomill {
namespace {

// A face boundary edge that is curved in (u,v) becomes this many polygon vertices.
constexpr int kSamplesPerCurvedEdge = 32;
// Open CASCADE's STEP and IGES writers format each real into a 24-byte buffer; with the 17
// significant digits written here, |x| >= 1e100 ("-1.2345678901234567E+100") would overflow it.
constexpr double kMaxWritableMagnitude = 1e99;

// ---------------------------------------------------------------------------------------------
// Open CASCADE set-up

// Forwards Open CASCADE's messages to photomill's log (stderr, and only with -v), and keeps the
// first failure since clear_problem() so that an InputError can quote the parser's complaint.
class LogPrinter : public Message_Printer {
  DEFINE_STANDARD_RTTI_INLINE(LogPrinter, Message_Printer)

public:
  void clear_problem() { problem_.clear(); }
  const std::string& problem() const { return problem_; }

protected:
  void send(const TCollection_AsciiString& text, const Message_Gravity gravity) const override {
    if (gravity < myTraceLevel) return;
    std::string_view message(text.ToCString());
    while (!message.empty() && (message.front() == '*' || std::isspace(static_cast<unsigned char>(message.front())))) {
      message.remove_prefix(1);
    }
    while (!message.empty() && (message.back() == '*' || std::isspace(static_cast<unsigned char>(message.back())))) {
      message.remove_suffix(1);
    }
    if (message.empty()) return;
    if (gravity >= Message_Fail && problem_.empty()) problem_ = message;
    log::debug("Open CASCADE: " + std::string(message));
  }

private:
  mutable std::string problem_;
};

// The printer that replaces the default one. Open CASCADE's messenger is global and starts with
// a printer to std::cout.
LogPrinter& occt_printer() {
  static const Handle(LogPrinter) printer = [] {
    Handle(LogPrinter) p = new LogPrinter;
    const Handle(Message_Messenger)& messenger = Message::DefaultMessenger();
    messenger->ChangePrinters().Clear();
    messenger->AddPrinter(p);
    STEPControl_Controller::Init();
    IGESControl_Controller::Init();
    return p;
  }();
  return *printer;
}

// Called at the start of every public function. The Interface_Static parameters are global and
// any other code in the process may change them, so they are set again on every call. Writers
// and readers read them when constructed: construct them after this.
void prepare_occt() {
  occt_printer().clear_problem();
  // Open CASCADE 7.6 has no "*.verbose" parameters; silence comes from the messenger alone.
  Interface_Static::SetCVal("xstep.cascade.unit", "MM");  // unit of the shapes read and written
  Interface_Static::SetCVal("write.step.unit", "MM");
  Interface_Static::SetCVal("write.iges.unit", "MM");
  Interface_Static::SetCVal("write.step.schema", "AP214IS");
  Interface_Static::SetCVal("write.iges.brep.mode", "Faces");  // trimmed surface (144) per face
  Interface_Static::SetCVal("write.step.product.name", "photomill");
  Interface_Static::SetCVal("write.iges.header.product", "photomill");
  // 1 (the default) lets the IGES reader remove knots of C0 B-splines, or split them into C1
  // pieces, to raise continuity: keep surfaces as written.
  Interface_Static::SetIVal("read.iges.bspline.continuity", 0);
}

// Runs `body`, turning Open CASCADE's exceptions into InputError(path, 0, ...).
template <typename Body>
auto guarded(const std::string& path, const char* action, Body&& body) -> decltype(body()) {
  try {
    prepare_occt();
    return body();
  } catch (const Standard_Failure& e) {
    const char* message = e.GetMessageString();
    throw InputError(path, 0,
                     std::string("Open CASCADE failed to ") + action + ": " +
                         e.DynamicType()->Name() +
                         (message != nullptr && *message != '\0' ? std::string(": ") + message : ""));
  }
}

// 17 significant digits round-trip every double (max_digits10). SetFormat also turns off the
// trailing-zero suppression, which only scans the first 16 characters and would truncate these.
// Magnitudes below 1e-99 (three-digit exponents) get one digit less to fit the 24-byte buffer.
void use_exact_reals(Interface_FloatWriter& writer) {
  writer.SetFormat("%.16E");
  writer.SetFormatForRange("%.15E", 0.0, 1e-99);
}

// ---------------------------------------------------------------------------------------------
// Conversion between photomill's full knot vectors and Open CASCADE's knots + multiplicities

struct KnotsAndMults {
  TColStd_Array1OfReal knots;
  TColStd_Array1OfInteger mults;
};

KnotsAndMults distinct_knots(const std::vector<double>& full) {
  std::vector<double> knots;
  std::vector<int> mults;
  for (double k : full) {
    if (!knots.empty() && k == knots.back()) {
      ++mults.back();
    } else {
      knots.push_back(k);
      mults.push_back(1);
    }
  }
  const int n = static_cast<int>(knots.size());
  KnotsAndMults out{TColStd_Array1OfReal(1, n), TColStd_Array1OfInteger(1, n)};
  for (int i = 0; i < n; ++i) {
    out.knots(i + 1) = knots[static_cast<std::size_t>(i)];
    out.mults(i + 1) = mults[static_cast<std::size_t>(i)];
  }
  return out;
}

Handle(Geom_BSplineSurface) to_occt(const BSplineSurface& s) {
  const KnotsAndMults u = distinct_knots(s.knots_u);
  const KnotsAndMults v = distinct_knots(s.knots_v);
  TColgp_Array2OfPnt poles(1, s.num_poles_u, 1, s.num_poles_v);
  for (int i = 0; i < s.num_poles_u; ++i) {
    for (int j = 0; j < s.num_poles_v; ++j) {
      const Eigen::Vector3d& p = s.pole(i, j);
      poles(i + 1, j + 1) = gp_Pnt(p.x(), p.y(), p.z());
    }
  }
  if (!s.rational()) {
    return new Geom_BSplineSurface(poles, u.knots, v.knots, u.mults, v.mults, s.degree_u, s.degree_v);
  }
  TColStd_Array2OfReal weights(1, s.num_poles_u, 1, s.num_poles_v);
  for (int i = 0; i < s.num_poles_u; ++i) {
    for (int j = 0; j < s.num_poles_v; ++j) {
      weights(i + 1, j + 1) = s.weights[static_cast<std::size_t>(i) * s.num_poles_v + j];
    }
  }
  return new Geom_BSplineSurface(poles, weights, u.knots, v.knots, u.mults, v.mults, s.degree_u,
                                 s.degree_v);
}

std::vector<double> full_knots(const TColStd_Array1OfReal& knots, const TColStd_Array1OfInteger& mults) {
  std::vector<double> full;
  for (int i = knots.Lower(); i <= knots.Upper(); ++i) full.insert(full.end(), mults(i), knots(i));
  return full;
}

BSplineSurface from_occt(Handle(Geom_BSplineSurface) g) {
  if (g->IsUPeriodic() || g->IsVPeriodic()) {
    // Periodic knots and poles are stored folded; unfold them into the ordinary form.
    g = Handle(Geom_BSplineSurface)::DownCast(g->Copy());
    if (g->IsUPeriodic()) g->SetUNotPeriodic();
    if (g->IsVPeriodic()) g->SetVNotPeriodic();
  }
  BSplineSurface s;
  s.degree_u = g->UDegree();
  s.degree_v = g->VDegree();
  s.num_poles_u = g->NbUPoles();
  s.num_poles_v = g->NbVPoles();
  TColStd_Array1OfReal uk(1, g->NbUKnots()), vk(1, g->NbVKnots());
  TColStd_Array1OfInteger um(1, g->NbUKnots()), vm(1, g->NbVKnots());
  g->UKnots(uk);
  g->VKnots(vk);
  g->UMultiplicities(um);
  g->VMultiplicities(vm);
  s.knots_u = full_knots(uk, um);
  s.knots_v = full_knots(vk, vm);
  const bool rational = g->IsURational() || g->IsVRational();
  for (int i = 1; i <= s.num_poles_u; ++i) {
    for (int j = 1; j <= s.num_poles_v; ++j) {
      const gp_Pnt p = g->Pole(i, j);
      s.poles_mm.emplace_back(p.X(), p.Y(), p.Z());
      if (rational) s.weights.push_back(g->Weight(i, j));
    }
  }
  return s;
}

// ---------------------------------------------------------------------------------------------
// Writing

void check_writable(const BSplineSurface& s, const std::string& path) {
  validate_surface(s, path);
  auto fail = [&](const std::string& why) { throw InputError(path, 0, "cannot write the surface: " + why); };
  auto too_big = [](double x) { return std::abs(x) > kMaxWritableMagnitude; };
  if (std::any_of(s.knots_u.begin(), s.knots_u.end(), too_big) ||
      std::any_of(s.knots_v.begin(), s.knots_v.end(), too_big) ||
      std::any_of(s.weights.begin(), s.weights.end(), too_big) ||
      std::any_of(s.poles_mm.begin(), s.poles_mm.end(),
                  [](const Eigen::Vector3d& p) { return p.cwiseAbs().maxCoeff() > kMaxWritableMagnitude; })) {
    fail("a knot, pole or weight exceeds 1e99 in magnitude");
  }
  const double u0 = s.knots_u[static_cast<std::size_t>(s.degree_u)];
  const double u1 = s.knots_u[static_cast<std::size_t>(s.num_poles_u)];
  const double v0 = s.knots_v[static_cast<std::size_t>(s.degree_v)];
  const double v1 = s.knots_v[static_cast<std::size_t>(s.num_poles_v)];
  for (std::size_t k = 0; k < s.boundary_uv.size(); ++k) {
    const Eigen::Vector2d& a = s.boundary_uv[k];
    if (a.x() < u0 || a.x() > u1 || a.y() < v0 || a.y() > v1) {
      fail("boundary vertex " + std::to_string(k) + " lies outside the parameter domain");
    }
    if (a == s.boundary_uv[(k + 1) % s.boundary_uv.size()]) {
      fail("boundary vertex " + std::to_string(k) + " repeats the next one");
    }
  }
}

// The face of `g`: its whole domain, or the region inside `boundary` (straight edges in (u,v)).
TopoDS_Face make_face(const Handle(Geom_BSplineSurface)& g, const std::vector<Eigen::Vector2d>& boundary,
                      const std::string& path) {
  auto fail = [&](const char* what) { throw InputError(path, 0, std::string("cannot build the face: ") + what); };
  if (boundary.empty()) {
    BRepBuilderAPI_MakeFace face(g, Precision::Confusion());
    if (!face.IsDone()) fail("Open CASCADE refuses the surface");
    return face.Face();
  }
  std::vector<TopoDS_Vertex> vertices;
  for (const Eigen::Vector2d& uv : boundary) {
    vertices.push_back(BRepBuilderAPI_MakeVertex(g->Value(uv.x(), uv.y())).Vertex());
  }
  BRepBuilderAPI_MakeWire wire;
  for (std::size_t k = 0; k < boundary.size(); ++k) {
    const std::size_t next = (k + 1) % boundary.size();
    const Eigen::Vector2d d = boundary[next] - boundary[k];
    Handle(Geom2d_Line) line =
        new Geom2d_Line(gp_Pnt2d(boundary[k].x(), boundary[k].y()), gp_Dir2d(d.x(), d.y()));
    BRepBuilderAPI_MakeEdge edge(line, g, vertices[k], vertices[next], 0.0, d.norm());
    if (!edge.IsDone()) fail("a boundary edge is degenerate");
    wire.Add(edge.Edge());
    if (!wire.IsDone()) fail("the boundary edges do not form a wire");
  }
  const TopoDS_Wire w = wire.Wire();
  BRepLib::BuildCurves3d(w);  // STEP and IGES carry the 3D edge curves as well as the pcurves
  BRepBuilderAPI_MakeFace face(g, w, Standard_True);
  if (!face.IsDone()) fail("Open CASCADE refuses the boundary");
  return face.Face();
}

std::ofstream open_output(const std::string& path) {
  std::ofstream out(path, std::ios::binary | std::ios::trunc);
  if (!out) throw InputError(path, 0, std::string("cannot create file: ") + std::strerror(errno));
  errno = 0;  // a failed write while printing leaves its reason here (close_output)
  return out;
}

// Flushes and closes `out`, which a writer has printed to; InputError with the system's reason
// (a full disk) unless every byte was written, close included.
void close_output(std::ofstream& out, bool printed, const std::string& path) {
  int error = out ? 0 : errno;  // a write failed while printing: nothing was written since
  if (error == 0) {
    out.flush();
    if (!out) error = errno;
  }
  out.close();
  if (error == 0 && !out) error = errno;
  if (!printed || !out) {
    throw InputError(path, 0, std::string("write failed") + (error != 0 ? std::string(": ") + std::strerror(error) : ""));
  }
}

// ---------------------------------------------------------------------------------------------
// Reading

enum class CadKind { Step, Iges };

std::string lower(std::string s) {
  std::transform(s.begin(), s.end(), s.begin(), [](unsigned char c) { return static_cast<char>(std::tolower(c)); });
  return s;
}

// The first `bytes` (a KiB unless told) of an existing, non-empty, readable file.
std::string file_head(const std::string& path, std::size_t bytes = 1024) {
  std::error_code ec;
  const auto status = std::filesystem::status(path, ec);
  if (!std::filesystem::exists(status)) throw InputError(path, 0, "cannot open: no such file");
  if (std::filesystem::is_directory(status)) throw InputError(path, 0, "cannot read: is a directory");
  std::ifstream in(path, std::ios::binary);
  if (!in) throw InputError(path, 0, std::string("cannot open: ") + std::strerror(errno));
  std::string head(bytes, '\0');
  in.read(head.data(), static_cast<std::streamsize>(head.size()));
  head.resize(static_cast<std::size_t>(in.gcount()));
  if (head.empty()) throw InputError(path, 0, "empty file");
  return head;
}

// ISO 10303-21: the file opens with "ISO-10303-21;" (tolerated: a UTF-8 BOM, blank space).
bool looks_like_step(std::string_view head) {
  if (head.substr(0, 3) == "\xEF\xBB\xBF") head.remove_prefix(3);
  while (!head.empty() && std::isspace(static_cast<unsigned char>(head.front()))) head.remove_prefix(1);
  return head.substr(0, 12) == "ISO-10303-21";
}

// Fixed 80-column records; column 73 of the first names its section: Start, Global, or C for
// the compressed form.
bool looks_like_iges(std::string_view head) {
  const std::string_view line = head.substr(0, head.find('\n'));
  return line.size() >= 73 && (line[72] == 'S' || line[72] == 'G' || line[72] == 'C');
}

void check_kind(const std::string& path, CadKind kind) {
  const std::string head = file_head(path);
  if (kind == CadKind::Step && !looks_like_step(head)) {
    throw InputError(path, 0, "not a STEP file: it does not begin with ISO-10303-21");
  }
  if (kind == CadKind::Iges && !looks_like_iges(head)) {
    throw InputError(path, 0, "not an IGES file: its first line is not an 80-column Start or Global record");
  }
}

Handle(Geom_BSplineSurface) as_bspline(Handle(Geom_Surface) surface) {
  if (auto trimmed = Handle(Geom_RectangularTrimmedSurface)::DownCast(surface); !trimmed.IsNull()) {
    surface = trimmed->BasisSurface();
  }
  return Handle(Geom_BSplineSurface)::DownCast(surface);
}

// Parameters at which the pcurve of an edge has corners, from `first` to `last` inclusive:
// the ends of a line, also the interior knots of a degree-1 B-spline, and evenly spaced samples
// of anything curved.
std::vector<double> corner_parameters(const Handle(Geom2d_Curve)& pcurve, double first, double last) {
  Handle(Geom2d_Curve) c = pcurve;
  if (auto trimmed = Handle(Geom2d_TrimmedCurve)::DownCast(c); !trimmed.IsNull()) c = trimmed->BasisCurve();
  const auto bspline = Handle(Geom2d_BSplineCurve)::DownCast(c);
  const auto bezier = Handle(Geom2d_BezierCurve)::DownCast(c);
  const bool polyline = !Handle(Geom2d_Line)::DownCast(c).IsNull() ||
                        (!bspline.IsNull() && bspline->Degree() == 1) ||
                        (!bezier.IsNull() && bezier->Degree() == 1);
  std::vector<double> ts{first};
  if (!polyline) {
    for (int k = 1; k < kSamplesPerCurvedEdge; ++k) ts.push_back(first + (last - first) * k / kSamplesPerCurvedEdge);
  } else if (!bspline.IsNull()) {
    for (int i = 1; i <= bspline->NbKnots(); ++i) {
      if (bspline->Knot(i) > first && bspline->Knot(i) < last) ts.push_back(bspline->Knot(i));
    }
  }
  ts.push_back(last);
  return ts;
}

double signed_area(const std::vector<Eigen::Vector2d>& polygon) {
  double twice = 0;
  for (std::size_t k = 0; k < polygon.size(); ++k) {
    const Eigen::Vector2d& a = polygon[k];
    const Eigen::Vector2d& b = polygon[(k + 1) % polygon.size()];
    twice += a.x() * b.y() - b.x() * a.y();
  }
  return twice / 2;
}

// The outer wire of `face` as a counter-clockwise polygon in the (u,v) of `g`; empty when it is
// the whole parameter rectangle of `g` or cannot be followed.
std::vector<Eigen::Vector2d> outer_boundary(const TopoDS_Face& face, const Geom_BSplineSurface& g) {
  const TopoDS_Wire wire = BRepTools::OuterWire(face);
  if (wire.IsNull()) return {};
  std::vector<Eigen::Vector2d> polygon;
  for (BRepTools_WireExplorer it(wire, face); it.More(); it.Next()) {
    const TopoDS_Edge& edge = it.Current();
    double first = 0, last = 0;
    const Handle(Geom2d_Curve) pcurve = BRep_Tool::CurveOnSurface(edge, face, first, last);
    if (pcurve.IsNull()) return {};
    std::vector<double> ts = corner_parameters(pcurve, first, last);
    if (edge.Orientation() == TopAbs_REVERSED) std::reverse(ts.begin(), ts.end());
    ts.pop_back();  // the next edge starts there
    for (double t : ts) {
      const gp_Pnt2d uv = pcurve->Value(t);
      polygon.emplace_back(uv.X(), uv.Y());
    }
  }
  double u0 = 0, u1 = 0, v0 = 0, v1 = 0;
  g.Bounds(u0, u1, v0, v1);
  const double tolerance = 1e-9 * std::max(u1 - u0, v1 - v0);
  std::vector<Eigen::Vector2d> simple;  // without repeated vertices (seams, degenerate edges)
  for (const Eigen::Vector2d& p : polygon) {
    if (simple.empty() || (p - simple.back()).norm() > tolerance) simple.push_back(p);
  }
  while (simple.size() > 1 && (simple.front() - simple.back()).norm() <= tolerance) simple.pop_back();
  if (simple.size() < 3) return {};
  double area = signed_area(simple);
  if (area < 0) {
    std::reverse(simple.begin(), simple.end());
    area = -area;
  }
  // Inside the rectangle with the rectangle's area: it is the rectangle.
  const bool inside = std::all_of(simple.begin(), simple.end(), [&](const Eigen::Vector2d& p) {
    return p.x() >= u0 - tolerance && p.x() <= u1 + tolerance && p.y() >= v0 - tolerance && p.y() <= v1 + tolerance;
  });
  const double domain_area = (u1 - u0) * (v1 - v0);
  if (inside && std::abs(area - domain_area) <= 1e-9 * domain_area) return {};
  return simple;
}

// The faces of `shape` as B-spline surfaces, which way each faces, and (mesh_deflection_mm > 0)
// a triangle mesh of them all.
CadPart faces_of(const TopoDS_Shape& shape, const std::string& path, double mesh_deflection_mm, bool mesh_one_face) {
  CadPart part;
  for (TopExp_Explorer it(shape, TopAbs_FACE); it.More(); it.Next()) {
    TopoDS_Face face = TopoDS::Face(it.Current());
    const bool reversed = face.Orientation() == TopAbs_REVERSED;
    // BRep_Tool::Surface without a location argument applies the face's placement.
    Handle(Geom_BSplineSurface) g = as_bspline(BRep_Tool::Surface(face));
    if (g.IsNull()) {
      BRepBuilderAPI_NurbsConvert converted(face, Standard_True);
      face = TopoDS::Face(converted.Shape());
      g = as_bspline(BRep_Tool::Surface(face));
    }
    const std::string which = "face " + std::to_string(part.faces.size() + 1);
    if (g.IsNull()) throw InputError(path, 0, which + ": cannot convert its surface to a B-spline");
    BSplineSurface s = from_occt(g);
    s.boundary_uv = outer_boundary(face, *g);
    validate_surface(s, path + " (" + which + ")");
    part.faces.push_back(std::move(s));
    part.reversed.push_back(reversed);
  }
  if (part.faces.empty()) throw InputError(path, 0, "no faces: the file holds no surface geometry");
  if (mesh_deflection_mm > 0 && (part.faces.size() > 1 || mesh_one_face)) {
    // Linear deflection in mm (not relative to the face size); 0.2 rad angular deflection; the
    // faces meshed in parallel.
    BRepMesh_IncrementalMesh mesher(shape, mesh_deflection_mm, Standard_False, 0.2, Standard_True);
    int face_index = 0;
    for (TopExp_Explorer it(shape, TopAbs_FACE); it.More(); it.Next(), ++face_index) {
      const TopoDS_Face& face = TopoDS::Face(it.Current());
      TopLoc_Location loc;
      const Handle(Poly_Triangulation) tri = BRep_Tool::Triangulation(face, loc);
      if (tri.IsNull() || tri->NbTriangles() == 0) {
        throw InputError(path, 0, "face " + std::to_string(face_index + 1) + ": Open CASCADE could not mesh it");
      }
      const gp_Trsf placement = loc.Transformation();
      const int base = static_cast<int>(part.mesh_vertices.size());
      for (int n = 1; n <= tri->NbNodes(); ++n) {
        const gp_Pnt p = tri->Node(n).Transformed(placement);
        part.mesh_vertices.emplace_back(p.X(), p.Y(), p.Z());
      }
      for (int t = 1; t <= tri->NbTriangles(); ++t) {
        int a = 0, b = 0, c = 0;
        tri->Triangle(t).Get(a, b, c);
        part.mesh_triangles.push_back({base + a - 1, base + b - 1, base + c - 1});
        part.triangle_face.push_back(face_index);
      }
    }
  }
  return part;
}

// ": <the reader's first complaint>", or the reader's status when it said nothing.
std::string why(IFSelect_ReturnStatus status) {
  const std::string& problem = occt_printer().problem();
  if (!problem.empty()) return ": " + problem;
  switch (status) {
    case IFSelect_RetVoid: return ": nothing to read";
    case IFSelect_RetError: return ": error";
    case IFSelect_RetFail: return ": failure";
    default: return "";
  }
}

// Open CASCADE's readers keep going past an entity whose parameters cannot be read (a wrong
// parameter count, a list that is not a list): the entity is created with those fields unset,
// and the transfer later dereferences them (a malformed B_SPLINE_CURVE_WITH_KNOTS crashed in
// StepGeom_BSplineCurveWithKnots::NbKnotMultiplicities). The reader records a "Fail" check for
// each such entity in the model's syntactic check list (IFSelect_WorkSession::ModelCheckList
// with complete = false, filled while the file is loaded); a file with any of them is refused
// before anything is transferred. The semantic checks (complete = true) are not used: they also
// fail on geometry that the transfer handles itself.
void refuse_unreadable_entities(XSControl_Reader& reader, const std::string& path) {
  const Interface_CheckIterator checks = reader.WS()->ModelCheckList(Standard_False);
  const Handle(Interface_InterfaceModel) model = reader.Model();
  std::string first;
  int failing = 0;
  for (checks.Start(); checks.More(); checks.Next()) {
    const Handle(Interface_Check)& check = checks.Value();
    if (check.IsNull() || !check->HasFailed()) continue;
    if (++failing > 1) continue;
    const Standard_Integer number = checks.Number();
    std::string which;  // empty for a check on the whole file
    if (number > 0 && !model.IsNull() && number <= model->NbEntities()) {
      const Handle(TCollection_HAsciiString) label = model->StringLabel(model->Value(number));
      which = "entity " + std::string(label.IsNull() ? "#" + std::to_string(number) : label->ToCString());
      if (check->HasEntity()) which += std::string(" (") + check->Entity()->DynamicType()->Name() + ")";
      which += ": ";
    }
    first = which + check->CFail(1);
  }
  if (failing == 0) return;
  throw InputError(path, 0,
                   "cannot be read: " + first +
                       (failing > 1 ? " (and " + std::to_string(failing - 1) + " more failing entities)" : ""));
}

// Open CASCADE 7.6's STEP and IGES file parsers themselves crash on some malformed files, inside
// ReadFile, before any check list exists: a STEP entity that could not be built is added to the
// model as a null handle (Interface_InterfaceModel::AddEntity -> Standard_Transient::IsKind on
// null), an IGES B-spline surface whose parameters failed to read is initialised from null
// arrays (IGESGeom_ToolBSplineSurface::ReadOwnParams -> IGESGeom_BSplineSurface::Init); both
// found by fuzzing within minutes, with more of the kind behind them. Guarding every entity type
// OCCT dereferences would mean re-parsing both formats, so the whole read runs in a child process
// instead (fork, no exec: the child inherits Open CASCADE already set up). The child sends back
// the faces in photomill's surface text (exact: shortest round-trip decimals) or the InputError
// it threw; a child that dies - by a signal, or a sanitizer's report - is a file Open CASCADE
// cannot read, answered with an InputError, and the calling process is untouched.
// A reader that never ends is stopped by the kernel after this much CPU time (RLIMIT_CPU: SIGXCPU)
// and answered like a crash: Open CASCADE's STEP reader was once seen spinning for 30 minutes on
// tests/fuzz/corpus/step/crash-79050776544b7cdb1805831b0dbdfdd18e986b58, which it refuses in
// milliseconds every other time (not reproduced in 30 runs).
constexpr rlim_t kReaderCpuLimitS = 600;

CadPart read_isolated(const std::string& path, const char* format, const std::function<CadPart()>& read) {
  int fds[2];
  if (::pipe(fds) != 0) throw InputError(path, 0, std::string("cannot create a pipe: ") + std::strerror(errno));
  const pid_t pid = ::fork();
  if (pid < 0) {
    const int err = errno;
    ::close(fds[0]);
    ::close(fds[1]);
    throw InputError(path, 0, std::string("cannot start the ") + format + " reader process: " + std::strerror(err));
  }
  if (pid == 0) {
    ::close(fds[0]);
    // Under a sanitizer, a crash in the child must not run the parent's death callback (libFuzzer
    // would record the input as a crash of the harness): the child only reports to the parent.
    if (__sanitizer_set_death_callback != nullptr) __sanitizer_set_death_callback(nullptr);
    // The CPU limit's signal kills the child by default: not the tool's handler, which would
    // remove the parent's temporary outputs (formats/tool.cpp).
    ::signal(SIGXCPU, SIG_DFL);
    rlimit cpu{};
    if (::getrlimit(RLIMIT_CPU, &cpu) == 0 && (cpu.rlim_cur == RLIM_INFINITY || cpu.rlim_cur > kReaderCpuLimitS)) {
      cpu.rlim_cur = kReaderCpuLimitS;
      ::setrlimit(RLIMIT_CPU, &cpu);
    }
    std::ostringstream reply;
    try {
      const CadPart part = read();
      reply << "faces " << part.faces.size() << "\n";
      for (std::size_t i = 0; i < part.faces.size(); ++i) {
        std::ostringstream text;
        write_surface(text, part.faces[i]);
        reply << part.reversed[i] << " " << text.str().size() << "\n" << text.str();
      }
      reply.precision(17);
      reply << "mesh " << part.mesh_vertices.size() << " " << part.mesh_triangles.size() << "\n";
      for (const Eigen::Vector3d& v : part.mesh_vertices) reply << v.x() << " " << v.y() << " " << v.z() << "\n";
      for (std::size_t t = 0; t < part.mesh_triangles.size(); ++t) {
        const auto& tri = part.mesh_triangles[t];
        reply << tri[0] << " " << tri[1] << " " << tri[2] << " " << part.triangle_face[t] << "\n";
      }
    } catch (const InputError& e) {
      reply.str("");
      reply << "error " << e.line() << "\n" << e.source().size() << "\n" << e.source() << e.message();
    } catch (const std::exception& e) {
      reply.str("");
      reply << "error 0\n" << path.size() << "\n" << path << e.what();
    }
    const std::string bytes = reply.str();
    for (std::size_t done = 0; done < bytes.size();) {
      const ssize_t n = ::write(fds[1], bytes.data() + done, bytes.size() - done);
      if (n < 0 && errno == EINTR) continue;
      if (n <= 0) ::_exit(3);
      done += static_cast<std::size_t>(n);
    }
    ::_exit(0);  // no static destructors, no atexit handlers, no leak check of the parent's state
  }
  ::close(fds[1]);
  std::string bytes;
  char buf[1 << 16];
  for (;;) {
    const ssize_t n = ::read(fds[0], buf, sizeof buf);
    if (n < 0 && errno == EINTR) continue;
    if (n <= 0) break;
    bytes.append(buf, static_cast<std::size_t>(n));
  }
  ::close(fds[0]);
  int status = 0;
  while (::waitpid(pid, &status, 0) < 0 && errno == EINTR) {
  }
  if (WIFSIGNALED(status) && WTERMSIG(status) == SIGXCPU) {
    throw InputError(path, 0, std::string("Open CASCADE's ") + format + " reader did not finish within " +
                                  std::to_string(kReaderCpuLimitS) + " s of CPU time: a malformed or enormous file");
  }
  if (!WIFEXITED(status) || WEXITSTATUS(status) != 0) {
    const std::string how = WIFSIGNALED(status) ? std::string("signal ") + ::strsignal(WTERMSIG(status))
                                                : "exit status " + std::to_string(WEXITSTATUS(status));
    throw InputError(path, 0, std::string("malformed ") + format + " file: Open CASCADE's reader crashed on it (" + how + ")");
  }
  std::istringstream in(bytes);
  std::string kind;
  in >> kind;
  if (kind == "error") {
    std::size_t line = 0, source_size = 0;
    in >> line >> source_size;
    in.get();
    std::string source(source_size, '\0');
    in.read(source.data(), static_cast<std::streamsize>(source_size));
    std::string message((std::istreambuf_iterator<char>(in)), {});
    throw InputError(source, line, message);
  }
  std::size_t count = 0;
  if (kind != "faces" || !(in >> count)) throw InputError(path, 0, std::string("the ") + format + " reader process gave no answer");
  CadPart part;
  for (std::size_t i = 0; i < count; ++i) {
    std::size_t size = 0;
    bool reversed = false;
    in >> reversed >> size;
    in.get();
    std::string text(size, '\0');
    in.read(text.data(), static_cast<std::streamsize>(size));
    std::istringstream face(text);
    part.faces.push_back(read_surface(face, path + " (face " + std::to_string(i + 1) + ")"));
    part.reversed.push_back(reversed);
  }
  std::string mesh;
  std::size_t nv = 0, nt = 0;
  if (!(in >> mesh >> nv >> nt) || mesh != "mesh") throw InputError(path, 0, std::string("the ") + format + " reader process gave a short answer");
  part.mesh_vertices.resize(nv);
  for (Eigen::Vector3d& v : part.mesh_vertices) in >> v.x() >> v.y() >> v.z();
  part.mesh_triangles.resize(nt);
  part.triangle_face.resize(nt);
  for (std::size_t t = 0; t < nt; ++t) {
    auto& tri = part.mesh_triangles[t];
    in >> tri[0] >> tri[1] >> tri[2] >> part.triangle_face[t];
  }
  if (!in) throw InputError(path, 0, std::string("the ") + format + " reader process gave a short answer");
  return part;
}

}  // namespace

namespace {

// The login name of the user running the program ('' when the system has none for the uid).
std::string login_name() {
  const passwd* pw = ::getpwuid(::getuid());
  return pw != nullptr && pw->pw_name != nullptr ? pw->pw_name : "";
}

std::string header_file_name(const CadHeader& header, const std::string& path) {
  return header.file_name.empty() ? std::filesystem::path(path).filename().string() : header.file_name;
}

Handle(TCollection_HAsciiString) hstring(const std::string& s) { return new TCollection_HAsciiString(s.c_str()); }
// A STEP header list of one string ('author', ...).
Handle(Interface_HArray1OfHAsciiString) one_string(const std::string& s) {
  Handle(Interface_HArray1OfHAsciiString) list = new Interface_HArray1OfHAsciiString(1, 1);
  list->SetValue(1, hstring(s));
  return list;
}

const std::string& originating_system() {
  static const std::string s = std::string("photomill ") + PHOTOMILL_VERSION;
  return s;
}

// STEP's FILE_NAME and FILE_DESCRIPTION in place of Open CASCADE's defaults ('Author',
// 'Open CASCADE', 'Open CASCADE Model'); the time stamp Open CASCADE set (now) is kept.
// STEP and IGES can only say millimetres. A surface in another unit (a reconstruction without a
// datum) says so in words a reader of photomill's files looks for (arbitrary_units_marked):
// STEP's FILE_DESCRIPTION, and a line of IGES's start section.
constexpr const char* kArbitraryUnitsMarker = "units arbitrary: NOT mm";

std::string described(const CadHeader& header, const BSplineSurface& surface) {
  if (surface.in_mm() || header.description.find(kArbitraryUnitsMarker) != std::string::npos) return header.description;
  if (header.description == CadHeader{}.description) {
    return std::string("B-spline surface fitted by photomill, ") + kArbitraryUnitsMarker +
           " (the point cloud was oriented without a datum), although the file says millimetres";
  }
  return header.description + " (" + kArbitraryUnitsMarker + ")";
}

void set_step_header(const Handle(StepData_StepModel)& model, const CadHeader& header, const std::string& path) {
  APIHeaderSection_MakeHeader h(model);
  h.SetName(hstring(header_file_name(header, path)));
  h.SetAuthor(one_string(login_name()));
  h.SetOrganization(one_string(""));
  h.SetOriginatingSystem(hstring(originating_system()));
  h.SetPreprocessorVersion(hstring(std::string("Open CASCADE ") + OCC_VERSION_COMPLETE));
  h.SetAuthorisation(hstring(""));
  h.SetDescription(one_string(header.description));
  h.Apply(model);
}

// IGES's global section: the file name, the system, the author and an empty company.
void set_iges_header(const Handle(IGESData_IGESModel)& model, const CadHeader& header, const std::string& path) {
  IGESData_GlobalSection g = model->GlobalSection();
  const std::string name = header_file_name(header, path);
  g.SetSendName(hstring(std::filesystem::path(name).stem().string()));  // the product: the file's stem
  g.SetFileName(hstring(name));
  g.SetSystemId(hstring(originating_system()));
  g.SetInterfaceVersion(hstring(std::string("Open CASCADE ") + OCC_VERSION_COMPLETE));
  g.SetAuthorName(hstring(login_name()));
  g.SetCompanyName(hstring(""));
  model->SetGlobalSection(g);
}

}  // namespace

void write_step(const BSplineSurface& surface, const std::string& path, const CadHeader& header) {
  check_writable(surface, path);
  guarded(path, "write STEP", [&] {
    const TopoDS_Face face = make_face(to_occt(surface), surface.boundary_uv, path);
    STEPControl_Writer writer;
    if (writer.Transfer(face, STEPControl_AsIs) != IFSelect_RetDone) {
      throw InputError(path, 0, "Open CASCADE could not translate the face to STEP");
    }
    CadHeader h = header;
    h.description = described(header, surface);
    set_step_header(writer.Model(), h, path);
    // What STEPControl_Writer::Write does (StepSelect_WorkLibrary::WriteFile), with exact reals.
    StepData_StepWriter sw(writer.Model());
    use_exact_reals(sw.FloatWriter());
    sw.SendModel(Handle(StepData_Protocol)::DownCast(writer.WS()->Protocol()));
    std::ofstream out = open_output(path);
    const bool printed = sw.Print(out);
    close_output(out, printed, path);
  });
}

void write_iges(const BSplineSurface& surface, const std::string& path, const CadHeader& header) {
  check_writable(surface, path);
  guarded(path, "write IGES", [&] {
    const TopoDS_Face face = make_face(to_occt(surface), surface.boundary_uv, path);
    IGESControl_Writer writer("MM", 0);
    if (!writer.AddShape(face)) throw InputError(path, 0, "Open CASCADE could not translate the face to IGES");
    writer.ComputeModel();
    set_iges_header(writer.Model(), header, path);
    if (!surface.in_mm()) {
      // The start section is free text for people, 72 columns a line: the marker on its own line.
      Handle(TColStd_HSequenceOfHAsciiString) start = new TColStd_HSequenceOfHAsciiString;
      start->Append(new TCollection_HAsciiString("B-spline surface fitted by photomill,"));
      start->Append(new TCollection_HAsciiString(kArbitraryUnitsMarker));
      start->Append(new TCollection_HAsciiString("(the point cloud was oriented without a datum)"));
      writer.Model()->SetStartSection(start);
    }
    // What IGESControl_Writer::Write does, with exact reals.
    IGESData_IGESWriter iw(writer.Model());
    use_exact_reals(iw.FloatWriter());
    iw.SendModel(IGESSelect_WorkLibrary::DefineProtocol());
    std::ofstream out = open_output(path);
    const bool printed = iw.Print(out);
    close_output(out, printed, path);
  });
}

namespace {

// Reads a STEP or IGES file with a Reader (STEPControl_Reader or IGESControl_Reader, both
// XSControl_Readers), made in the child process that reads the file.
template <class Reader>
CadPart read_with(const std::string& path, CadKind kind, const char* name, double mesh_deflection_mm, bool mesh_one_face) {
  check_kind(path, kind);
  const std::string action = std::string("read ") + name;
  return read_isolated(path, name, [&] {
    return guarded(path, action.c_str(), [&] {
      Reader reader;
      const IFSelect_ReturnStatus status = reader.ReadFile(path.c_str());
      if (status != IFSelect_RetDone) throw InputError(path, 0, std::string("not a readable ") + name + " file" + why(status));
      refuse_unreadable_entities(reader, path);
      reader.TransferRoots();
      return faces_of(reader.OneShape(), path, mesh_deflection_mm, mesh_one_face);
    });
  });
}

// STEP or IGES, by extension, else by the first line.
CadKind kind_of(const std::string& path) {
  const std::string ext = lower(std::filesystem::path(path).extension().string());
  if (ext == ".step" || ext == ".stp" || ext == ".p21") return CadKind::Step;
  if (ext == ".iges" || ext == ".igs") return CadKind::Iges;
  const std::string head = file_head(path);
  if (looks_like_step(head)) return CadKind::Step;
  if (looks_like_iges(head)) return CadKind::Iges;
  throw InputError(path, 0, "neither a STEP nor an IGES file");
}

// True if the file's header carries kArbitraryUnitsMarker (STEP's FILE_DESCRIPTION, which Open
// CASCADE wraps across lines, or IGES's start section), read as text from the file's start.
bool arbitrary_units_marked(const std::string& path) {
  const std::string head = file_head(path, 8192);
  std::string joined;
  for (char c : head) {
    if (c != '\n' && c != '\r') joined += c;
  }
  return joined.find(kArbitraryUnitsMarker) != std::string::npos;
}

CadPart read_part(const std::string& path, CadKind kind, double mesh_deflection_mm, bool mesh_one_face = false) {
  CadPart part = kind == CadKind::Step
                     ? read_with<STEPControl_Reader>(path, CadKind::Step, "STEP", mesh_deflection_mm, mesh_one_face)
                     : read_with<IGESControl_Reader>(path, CadKind::Iges, "IGES", mesh_deflection_mm, mesh_one_face);
  if (arbitrary_units_marked(path)) {
    for (BSplineSurface& f : part.faces) f.units = kSurfaceUnitArbitrary;
  }
  return part;
}

}  // namespace

std::vector<BSplineSurface> read_step(const std::string& path) { return read_part(path, CadKind::Step, 0).faces; }

std::vector<BSplineSurface> read_iges(const std::string& path) { return read_part(path, CadKind::Iges, 0).faces; }

std::vector<BSplineSurface> read_cad(const std::string& path) { return read_part(path, kind_of(path), 0).faces; }

CadPart read_cad_part(const std::string& path, double mesh_deflection_mm, bool mesh_one_face) {
  if (!(mesh_deflection_mm >= 0) || !std::isfinite(mesh_deflection_mm)) {
    throw InputError(path, 0, "the mesh deflection must be >= 0 mm (0: no mesh)");
  }
  return read_part(path, kind_of(path), mesh_deflection_mm, mesh_one_face);
}

}  // namespace photomill
