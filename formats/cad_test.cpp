// Tests for formats/cad.hpp: STEP and IGES round trips of hand-made B-spline surfaces, checked
// both with photomill's readers and with Open CASCADE's own, plus plane faces, units, errors,
// and silence on stdout. Files go to a fresh directory under temp_directory_path().
#include "formats/cad.hpp"
#include "formats/bspline.hpp"

#include <fcntl.h>
#include <sys/wait.h>
#include <unistd.h>

#include <cmath>
#include <cstdio>
#include <filesystem>
#include <fstream>
#include <iostream>
#include <numbers>
#include <random>
#include <sstream>
#include <string>
#include <vector>

#include <gtest/gtest.h>

#include <BRepBuilderAPI_MakeEdge.hxx>
#include <BRepPrimAPI_MakeBox.hxx>
#include <BRepBuilderAPI_MakeFace.hxx>
#include <BRepBuilderAPI_MakeWire.hxx>
#include <BRep_Builder.hxx>
#include <BRep_Tool.hxx>
#include <Geom_BSplineSurface.hxx>
#include <Geom_RectangularTrimmedSurface.hxx>
#include <IFSelect_ReturnStatus.hxx>
#include <IGESControl_Reader.hxx>
#include <IGESControl_Writer.hxx>
#include <Interface_Static.hxx>
#include <STEPControl_Reader.hxx>
#include <STEPControl_Writer.hxx>
#include <TColStd_Array1OfInteger.hxx>
#include <TColStd_Array1OfReal.hxx>
#include <TopExp_Explorer.hxx>
#include <TopoDS.hxx>
#include <TopoDS_Compound.hxx>
#include <TopoDS_Edge.hxx>
#include <TopoDS_Face.hxx>
#include <TopoDS_Wire.hxx>
#include <gp_Circ.hxx>
#include <gp_Cylinder.hxx>
#include <gp_Pln.hxx>

#include "formats/error.hpp"
#include "formats/log.hpp"

namespace photomill {
namespace {

namespace fs = std::filesystem;

enum class Format { Step, Iges };

std::string extension(Format f) { return f == Format::Step ? ".step" : ".iges"; }

void write_cad(Format f, const BSplineSurface& s, const std::string& path) {
  f == Format::Step ? write_step(s, path) : write_iges(s, path);
}

std::vector<BSplineSurface> read_cad_as(Format f, const std::string& path) {
  return f == Format::Step ? read_step(path) : read_iges(path);
}

// A fresh directory, removed with everything in it at the end of the test.
class TempDir {
public:
  TempDir() {
    std::random_device rd;
    dir_ = fs::temp_directory_path() /
           ("photomill_cad_test_" + std::to_string(::getpid()) + "_" + std::to_string(rd()));
    fs::create_directories(dir_);
  }
  ~TempDir() {
    std::error_code ec;
    fs::remove_all(dir_, ec);
  }
  std::string file(const std::string& name) const { return (dir_ / name).string(); }

private:
  fs::path dir_;
};

void write_text(const std::string& path, const std::string& text) {
  std::ofstream(path, std::ios::binary) << text;
}

// Bicubic, 6 x 5 poles, non-uniform interior knots, a domain other than [0,1]^2, and
// coordinates with all 17 digits in use.
BSplineSurface bicubic(bool rational) {
  BSplineSurface s;
  s.degree_u = 3;
  s.degree_v = 3;
  s.num_poles_u = 6;
  s.num_poles_v = 5;
  s.knots_u = {0, 0, 0, 0, 0.7, 1.1, 2.5, 2.5, 2.5, 2.5};
  s.knots_v = {-1, -1, -1, -1, 0.35, 2, 2, 2, 2};
  for (int i = 0; i < s.num_poles_u; ++i) {
    for (int j = 0; j < s.num_poles_v; ++j) {
      s.poles_mm.emplace_back(10.0 * i + std::sin(i + 0.3 * j) / 3, 8.0 * j - std::cos(1.7 * i) / 7,
                              std::exp(0.1 * i) * std::sqrt(j + 2.0) - 1.0 / 3);
      if (rational) s.weights.push_back(0.5 + 0.1 * ((i * 7 + j * 3) % 5) + 1.0 / 3);
    }
  }
  return s;
}

// Degree (2,1) with a double interior knot in u: only C0 there (Open CASCADE's IGES reader may
// remove knots or split such surfaces unless told not to).
BSplineSurface c0_surface() {
  BSplineSurface s;
  s.degree_u = 2;
  s.degree_v = 1;
  s.num_poles_u = 5;
  s.num_poles_v = 3;
  s.knots_u = {0, 0, 0, 0.4, 0.4, 1, 1, 1};
  s.knots_v = {0, 0, 0.25, 1, 1};
  for (int i = 0; i < s.num_poles_u; ++i) {
    for (int j = 0; j < s.num_poles_v; ++j) {
      s.poles_mm.emplace_back(5.0 * i, 4.0 * j, (i == 2 ? 3.0 : 0.0) + 0.1 * j * j);
    }
  }
  return s;
}

// Unclamped uniform knots in u (the domain is [2, 5]), a rational degree-1 direction in v.
BSplineSurface unclamped() {
  BSplineSurface s;
  s.degree_u = 2;
  s.degree_v = 1;
  s.num_poles_u = 5;
  s.num_poles_v = 2;
  s.knots_u = {0, 1, 2, 3, 4, 5, 6, 7};
  s.knots_v = {0, 0, 1, 1};
  for (int i = 0; i < s.num_poles_u; ++i) {
    for (int j = 0; j < s.num_poles_v; ++j) {
      s.poles_mm.emplace_back(3.0 * i, 7.0 * j, i % 2 == 0 ? 0.0 : 1.5);
      s.weights.push_back(j == 0 ? 1.0 : 0.75);
    }
  }
  return s;
}

BSplineSurface trimmed() {
  BSplineSurface s = bicubic(false);
  s.boundary_uv = {{0.2, -0.5}, {2.0, -0.8}, {2.3, 1.0}, {1.2, 1.9}, {0.1, 0.9}};
  return s;
}

// Poles and weights to `tolerance` relative, knots exactly, boundary vertices to `tolerance`.
void expect_same_surface(const BSplineSurface& expected, const BSplineSurface& actual,
                         double tolerance = 1e-9) {
  EXPECT_EQ(expected.degree_u, actual.degree_u);
  EXPECT_EQ(expected.degree_v, actual.degree_v);
  EXPECT_EQ(expected.knots_u, actual.knots_u);
  EXPECT_EQ(expected.knots_v, actual.knots_v);
  ASSERT_EQ(expected.num_poles_u, actual.num_poles_u);
  ASSERT_EQ(expected.num_poles_v, actual.num_poles_v);
  ASSERT_EQ(expected.poles_mm.size(), actual.poles_mm.size());
  for (std::size_t k = 0; k < expected.poles_mm.size(); ++k) {
    EXPECT_LE((expected.poles_mm[k] - actual.poles_mm[k]).norm(), tolerance * expected.poles_mm[k].norm())
        << "pole " << k;
  }
  ASSERT_EQ(expected.weights.size(), actual.weights.size());
  for (std::size_t k = 0; k < expected.weights.size(); ++k) {
    EXPECT_NEAR(expected.weights[k], actual.weights[k], tolerance * expected.weights[k]) << "weight " << k;
  }
  ASSERT_EQ(expected.boundary_uv.size(), actual.boundary_uv.size());
  for (std::size_t k = 0; k < expected.boundary_uv.size(); ++k) {
    EXPECT_LE((expected.boundary_uv[k] - actual.boundary_uv[k]).norm(), tolerance) << "boundary vertex " << k;
  }
}

// The B-spline surface of the only face of a STEP or IGES file, read by Open CASCADE alone.
Handle(Geom_BSplineSurface) occt_surface(Format f, const std::string& path) {
  TopoDS_Shape shape;
  if (f == Format::Step) {
    STEPControl_Reader reader;
    EXPECT_EQ(reader.ReadFile(path.c_str()), IFSelect_RetDone);
    reader.TransferRoots();
    shape = reader.OneShape();
  } else {
    IGESControl_Reader reader;
    EXPECT_EQ(reader.ReadFile(path.c_str()), IFSelect_RetDone);
    reader.TransferRoots();
    shape = reader.OneShape();
  }
  int faces = 0;
  Handle(Geom_Surface) surface;
  for (TopExp_Explorer it(shape, TopAbs_FACE); it.More(); it.Next(), ++faces) {
    surface = BRep_Tool::Surface(TopoDS::Face(it.Current()));
  }
  EXPECT_EQ(faces, 1);
  if (auto t = Handle(Geom_RectangularTrimmedSurface)::DownCast(surface); !t.IsNull()) surface = t->BasisSurface();
  return Handle(Geom_BSplineSurface)::DownCast(surface);
}

// Compares an Open CASCADE surface with photomill's, written out as distinct knots and
// multiplicities here rather than through cad.cpp's conversion.
void expect_occt_matches(const BSplineSurface& s, const Geom_BSplineSurface& g) {
  EXPECT_EQ(g.UDegree(), s.degree_u);
  EXPECT_EQ(g.VDegree(), s.degree_v);
  ASSERT_EQ(g.NbUPoles(), s.num_poles_u);
  ASSERT_EQ(g.NbVPoles(), s.num_poles_v);
  auto check_knots = [](const std::vector<double>& full, int n, auto knot, auto mult) {
    std::vector<double> expanded;
    for (int i = 1; i <= n; ++i) expanded.insert(expanded.end(), mult(i), knot(i));
    EXPECT_EQ(expanded, full);
  };
  check_knots(s.knots_u, g.NbUKnots(), [&](int i) { return g.UKnot(i); }, [&](int i) { return g.UMultiplicity(i); });
  check_knots(s.knots_v, g.NbVKnots(), [&](int i) { return g.VKnot(i); }, [&](int i) { return g.VMultiplicity(i); });
  EXPECT_EQ(g.IsURational() || g.IsVRational(), s.rational());
  for (int i = 0; i < s.num_poles_u; ++i) {
    for (int j = 0; j < s.num_poles_v; ++j) {
      const gp_Pnt p = g.Pole(i + 1, j + 1);
      const Eigen::Vector3d& q = s.pole(i, j);
      EXPECT_LE((Eigen::Vector3d(p.X(), p.Y(), p.Z()) - q).norm(), 1e-9 * q.norm()) << i << "," << j;
      if (s.rational()) {
        EXPECT_NEAR(g.Weight(i + 1, j + 1), s.weights[static_cast<std::size_t>(i) * s.num_poles_v + j], 1e-12);
      }
    }
  }
}

// Expects `call` to throw InputError naming `path` and containing `reason`.
template <typename Call>
void expect_input_error(Call&& call, const std::string& path, const std::string& reason) {
  try {
    call();
    ADD_FAILURE() << "no InputError for " << path;
  } catch (const InputError& e) {
    EXPECT_EQ(e.source(), path);
    EXPECT_EQ(e.line(), 0u);
    EXPECT_NE(std::string(e.what()).find(reason), std::string::npos) << e.what();
  }
}

// Writes a shape with Open CASCADE's own STEP writer.
// Open CASCADE 7.6 gotcha: the writer takes write.step.unit when it is constructed; set after,
// the file declares the new unit but keeps the coordinates unscaled.
void occt_write_step(const TopoDS_Shape& shape, const std::string& path, const char* unit = "MM") {
  { STEPControl_Writer init_statics; }  // registers write.step.unit on first use
  Interface_Static::SetCVal("write.step.unit", unit);
  STEPControl_Writer writer;
  ASSERT_EQ(writer.Transfer(shape, STEPControl_AsIs), IFSelect_RetDone);
  ASSERT_EQ(writer.Write(path.c_str()), IFSelect_RetDone);
  Interface_Static::SetCVal("write.step.unit", "MM");
}

// ---------------------------------------------------------------------------------------------

struct ChildOutput {
  int exit_code = -1;
  std::string out;  // what the child wrote to fd 1
  std::string err;  // what the child wrote to fd 2
};

// Runs `body` in a forked child whose fd 1 and fd 2 go to files; the child exits with body()'s
// result, or 2 if it throws.
template <typename Body>
ChildOutput run_in_child(Body&& body) {
  TempDir dir;
  const std::string out_path = dir.file("stdout.txt");
  const std::string err_path = dir.file("stderr.txt");
  std::cout.flush();
  std::fflush(stdout);
  std::fflush(stderr);
  const pid_t pid = ::fork();
  if (pid == 0) {
    const int out = ::open(out_path.c_str(), O_WRONLY | O_CREAT | O_TRUNC, 0644);
    const int err = ::open(err_path.c_str(), O_WRONLY | O_CREAT | O_TRUNC, 0644);
    if (out < 0 || err < 0 || ::dup2(out, 1) < 0 || ::dup2(err, 2) < 0) ::_exit(3);
    int code = 2;
    try {
      code = body();
    } catch (...) {
    }
    std::cout.flush();
    std::cerr.flush();
    std::fflush(stdout);
    std::fflush(stderr);
    ::_exit(code);
  }
  ChildOutput result;
  int status = 0;
  if (pid < 0 || ::waitpid(pid, &status, 0) != pid || !WIFEXITED(status)) return result;
  result.exit_code = WEXITSTATUS(status);
  auto slurp = [](const std::string& path) {
    std::ifstream in(path, std::ios::binary);
    std::ostringstream s;
    s << in.rdbuf();
    return s.str();
  };
  result.out = slurp(out_path);
  result.err = slurp(err_path);
  return result;
}

// Every entry point, failures included; 0 when each behaves as expected.
int exercise_every_entry_point(const TempDir& dir) {
  write_step(trimmed(), dir.file("a.step"));
  write_iges(bicubic(true), dir.file("a.iges"));
  if (read_step(dir.file("a.step")).size() != 1 || read_iges(dir.file("a.iges")).size() != 1 ||
      read_cad(dir.file("a.step")).size() != 1) {
    return 1;
  }
  write_text(dir.file("bad.step"), "ISO-10303-21;\nHEADER;\nthis is not STEP\n");
  occt_write_step(BRepBuilderAPI_MakeEdge(gp_Pnt(0, 0, 0), gp_Pnt(1, 0, 0)).Edge(), dir.file("edge.step"));
  for (const char* name : {"bad.step", "edge.step"}) {
    try {
      read_step(dir.file(name));
      return 1;
    } catch (const InputError&) {
    }
  }
  return 0;
}

// Open CASCADE prints statistics to stdout unless silenced. The child is fresh from Open
// CASCADE's first use when this test runs first (it is defined first, and ctest runs each test
// in its own process), so initialisation is covered too.
TEST(CadSilence, NothingOnStdoutOrStderr) {
  TempDir dir;
  const ChildOutput child = run_in_child([&] { return exercise_every_entry_point(dir); });
  EXPECT_EQ(child.exit_code, 0);
  EXPECT_EQ(child.out, "");
  EXPECT_EQ(child.err, "");
}

// With -v, Open CASCADE's messages reach the log on stderr; stdout stays clean.
TEST(CadSilence, VerboseMessagesGoToStderr) {
  TempDir dir;
  const ChildOutput child = run_in_child([&] {
    log::set_level(log::Level::Verbose);
    return exercise_every_entry_point(dir);
  });
  EXPECT_EQ(child.exit_code, 0);
  EXPECT_EQ(child.out, "");
  EXPECT_NE(child.err.find("Open CASCADE: "), std::string::npos) << child.err;
}

// ---------------------------------------------------------------------------------------------

struct RoundTripCase {
  const char* name;
  BSplineSurface (*make)();
};

class CadRoundTrip : public ::testing::TestWithParam<std::tuple<Format, RoundTripCase>> {};

TEST_P(CadRoundTrip, PhotomillAndOpenCascadeReadBackTheSameSurface) {
  const auto [format, c] = GetParam();
  TempDir dir;
  const std::string path = dir.file(std::string("surface") + extension(format));
  const BSplineSurface s = c.make();
  write_cad(format, s, path);

  const std::vector<BSplineSurface> read = read_cad_as(format, path);
  ASSERT_EQ(read.size(), 1u);
  expect_same_surface(s, read[0]);
  // 17 significant digits: untrimmed surfaces come back bit for bit.
  if (s.boundary_uv.empty()) {
    EXPECT_TRUE(read[0] == s);
  }
  // read_cad picks the reader by extension and gets the same.
  EXPECT_EQ(read_cad(path), read);

  const Handle(Geom_BSplineSurface) g = occt_surface(format, path);
  ASSERT_FALSE(g.IsNull());
  expect_occt_matches(s, *g);
}

void PrintTo(const RoundTripCase& c, std::ostream* os) { *os << c.name; }
void PrintTo(Format f, std::ostream* os) { *os << (f == Format::Step ? "STEP" : "IGES"); }

const RoundTripCase kCases[] = {
    {"bicubic", [] { return bicubic(false); }},
    {"rational", [] { return bicubic(true); }},
    {"c0", c0_surface},
    {"unclamped", unclamped},
    {"trimmed", trimmed},
};

INSTANTIATE_TEST_SUITE_P(All, CadRoundTrip,
                         ::testing::Combine(::testing::Values(Format::Step, Format::Iges),
                                            ::testing::ValuesIn(kCases)),
                         [](const auto& info) {
                           return std::string(std::get<0>(info.param) == Format::Step ? "Step_" : "Iges_") +
                                  std::get<1>(info.param).name;
                         });

TEST(Cad, FilesSayMillimetres) {
  TempDir dir;
  write_step(bicubic(false), dir.file("s.step"));
  write_iges(bicubic(false), dir.file("s.iges"));
  std::ifstream step(dir.file("s.step"));
  const std::string step_text((std::istreambuf_iterator<char>(step)), {});
  EXPECT_NE(step_text.find("SI_UNIT(.MILLI.,.METRE.)"), std::string::npos);
  EXPECT_NE(step_text.find("AUTOMOTIVE_DESIGN"), std::string::npos);  // AP214
  std::ifstream iges(dir.file("s.iges"));
  const std::string iges_text((std::istreambuf_iterator<char>(iges)), {});
  EXPECT_NE(iges_text.find("2HMM"), std::string::npos);  // global section: unit name
}

// The headers say what the file is and who wrote it, not Open CASCADE's placeholders (issue 27):
// the name given (not the temporary written to), photomill as the originating system.
// A surface of arbitrary scale: the file says millimetres (it can say nothing else) and, in words,
// that it is not; read back, its faces are of arbitrary scale. A surface in mm reads back in mm.
TEST(Cad, AnArbitraryScaleReadsBackAsArbitrary) {
  TempDir dir;
  for (const char* units : {"arbitrary", "mm"}) {
    BSplineSurface s = bicubic(false);
    s.units = units;
    for (const char* ext : {".step", ".igs"}) {
      const std::string path = dir.file(std::string("s_") + units + ext);
      if (std::string(ext) == ".step") {
        write_step(s, path);
      } else {
        write_iges(s, path);
      }
      std::ifstream in(path);
      std::string text((std::istreambuf_iterator<char>(in)), {});
      std::erase(text, '\n');  // Open CASCADE wraps STEP's strings
      EXPECT_EQ(text.find("NOT mm") != std::string::npos, std::string(units) == "arbitrary") << path;
      const std::vector<BSplineSurface> faces = read_cad(path);
      ASSERT_EQ(faces.size(), 1u) << path;
      EXPECT_EQ(faces[0].units, units) << path;
    }
  }
}

TEST(Cad, HeadersNameTheFileAndTheSystem) {
  TempDir dir;
  write_step(bicubic(false), dir.file(".tmp123"), CadHeader{"part.step"});
  write_iges(bicubic(false), dir.file(".tmp456"), CadHeader{"part.iges"});
  std::ifstream step(dir.file(".tmp123"));
  const std::string step_text((std::istreambuf_iterator<char>(step)), {});
  const std::string system = std::string("photomill ") + PHOTOMILL_VERSION;
  EXPECT_NE(step_text.find("FILE_NAME('part.step'"), std::string::npos) << step_text.substr(0, 600);
  EXPECT_NE(step_text.find("'" + system + "'"), std::string::npos) << step_text.substr(0, 600);
  EXPECT_NE(step_text.find("FILE_DESCRIPTION(('B-spline surface fitted by photomill, units mm')"), std::string::npos)
      << step_text.substr(0, 600);
  for (const char* placeholder : {"'Author'", "'Open CASCADE'", "Open CASCADE Model", "'Unknown'", ".tmp123"}) {
    EXPECT_EQ(step_text.find(placeholder), std::string::npos) << placeholder << "\n" << step_text.substr(0, 600);
  }
  std::ifstream iges(dir.file(".tmp456"));
  const std::string iges_text((std::istreambuf_iterator<char>(iges)), {});
  const std::string global = iges_text.substr(0, iges_text.find("D      1"));
  std::string flat;  // the global section's 72-column fields joined
  for (std::size_t k = 0; k + 72 <= global.size(); k += 81) {
    if (global[k + 72] == 'G') flat += global.substr(k, 72);
  }
  EXPECT_NE(flat.find("9Hpart.iges"), std::string::npos) << flat;
  EXPECT_NE(flat.find(std::to_string(system.size()) + "H" + system), std::string::npos) << flat;
  EXPECT_EQ(flat.find("Filename"), std::string::npos) << flat;
  EXPECT_EQ(flat.find("Open CASCADE IGES processor"), std::string::npos) << flat;  // the sender's product id
  EXPECT_EQ(read_step(dir.file(".tmp123")).size(), 1u);
}

// A file written in metres (by Open CASCADE itself) is read in millimetres.
TEST(Cad, ReadsOtherUnitsAsMillimetres) {
  TempDir dir;
  const BSplineSurface s = bicubic(true);
  // Build the face through photomill's writer, then re-export it with Open CASCADE in metres.
  write_step(s, dir.file("mm.step"));
  STEPControl_Reader reader;
  ASSERT_EQ(reader.ReadFile(dir.file("mm.step").c_str()), IFSelect_RetDone);
  reader.TransferRoots();
  const TopoDS_Shape face = reader.OneShape();
  occt_write_step(face, dir.file("m.step"), "M");
  {
    std::ifstream in(dir.file("m.step"));
    const std::string text((std::istreambuf_iterator<char>(in)), {});
    ASSERT_EQ(text.find(".MILLI."), std::string::npos);
  }
  IGESControl_Writer iges("M", 0);
  ASSERT_TRUE(iges.AddShape(face));
  iges.ComputeModel();
  ASSERT_TRUE(iges.Write(dir.file("m.iges").c_str()));

  for (const std::string name : {"m.step", "m.iges"}) {
    SCOPED_TRACE(name);
    const std::vector<BSplineSurface> read = read_cad(dir.file(name));
    ASSERT_EQ(read.size(), 1u);
    // Open CASCADE's own writers keep only 10 (IGES) to 13 (STEP) significant digits.
    expect_same_surface(s, read[0], 1e-7);
  }
}

// Faces on other surfaces come back as B-splines: a bounded plane is degree (1,1).
TEST(Cad, PlaneFaceReadsAsDegreeOneBSpline) {
  TempDir dir;
  const gp_Pln plane(gp_Pnt(0, 0, 5), gp_Dir(0, 0, 1));
  occt_write_step(BRepBuilderAPI_MakeFace(plane, -10, 20, -5, 15).Face(), dir.file("plane.step"));
  const std::vector<BSplineSurface> read = read_step(dir.file("plane.step"));
  ASSERT_EQ(read.size(), 1u);
  const BSplineSurface& s = read[0];
  EXPECT_EQ(s.degree_u, 1);
  EXPECT_EQ(s.degree_v, 1);
  EXPECT_EQ(s.num_poles_u, 2);
  EXPECT_EQ(s.num_poles_v, 2);
  EXPECT_FALSE(s.rational());
  EXPECT_TRUE(s.boundary_uv.empty());  // the face is the whole converted rectangle
  double xmin = 1e9, xmax = -1e9, ymin = 1e9, ymax = -1e9;
  for (const Eigen::Vector3d& p : s.poles_mm) {
    EXPECT_NEAR(p.z(), 5, 1e-12);
    xmin = std::min(xmin, p.x()), xmax = std::max(xmax, p.x());
    ymin = std::min(ymin, p.y()), ymax = std::max(ymax, p.y());
  }
  EXPECT_NEAR(xmin, -10, 1e-9);
  EXPECT_NEAR(xmax, 20, 1e-9);
  EXPECT_NEAR(ymin, -5, 1e-9);
  EXPECT_NEAR(ymax, 15, 1e-9);
}

// Every face is read, in order; a cylinder patch becomes a rational surface, quadratic around.
TEST(Cad, EveryFaceIsReadAndConverted) {
  TempDir dir;
  const double radius = 12.5;
  TopoDS_Compound both;
  BRep_Builder builder;
  builder.MakeCompound(both);
  builder.Add(both, BRepBuilderAPI_MakeFace(gp_Pln(gp_Pnt(0, 0, -1), gp_Dir(0, 0, 1)), 0, 1, 0, 1).Face());
  builder.Add(both, BRepBuilderAPI_MakeFace(gp_Cylinder(gp_Ax3(), radius), 0, std::numbers::pi / 2, 0, 30).Face());
  occt_write_step(both, dir.file("two.step"));
  const std::vector<BSplineSurface> read = read_step(dir.file("two.step"));
  ASSERT_EQ(read.size(), 2u);
  EXPECT_EQ(read[0].degree_u, 1);
  const BSplineSurface& cylinder = read[1];
  EXPECT_TRUE(cylinder.rational());
  EXPECT_EQ(std::max(cylinder.degree_u, cylinder.degree_v), 2);
  EXPECT_TRUE(cylinder.boundary_uv.empty());
  // The corner poles of a NURBS patch lie on the surface.
  for (const Eigen::Vector3d& p : {cylinder.poles_mm.front(), cylinder.poles_mm.back()}) {
    EXPECT_NEAR(std::hypot(p.x(), p.y()), radius, 1e-9);
  }
}

// A whole solid: a 10 x 20 x 30 mm box. Every face, which way it faces (S_u x S_v, reversed
// where the shell says so, points out of the box), and a mesh of them all within the deflection.
TEST(Cad, PartFacesPointOutwardsAndMeshTheSolid) {
  TempDir dir;
  occt_write_step(BRepPrimAPI_MakeBox(gp_Pnt(1, 2, 3), 10, 20, 30).Shape(), dir.file("box.step"));
  const CadPart part = read_cad_part(dir.file("box.step"), 0.01);
  ASSERT_EQ(part.faces.size(), 6u);
  ASSERT_EQ(part.reversed.size(), 6u);
  const Eigen::Vector3d centre(6, 12, 18);
  for (std::size_t i = 0; i < part.faces.size(); ++i) {
    const BSplineSurface& f = part.faces[i];
    const double u = 0.5 * (f.knots_u.front() + f.knots_u.back()), v = 0.5 * (f.knots_v.front() + f.knots_v.back());
    const SurfaceDerivatives d = surface_derivatives(f, u, v);
    const Eigen::Vector3d outward = (part.reversed[i] ? -1.0 : 1.0) * d.su.cross(d.sv);
    EXPECT_GT(outward.dot(d.p - centre), 0) << "face " << i;
  }
  ASSERT_GE(part.mesh_triangles.size(), 12u);
  ASSERT_EQ(part.triangle_face.size(), part.mesh_triangles.size());
  std::vector<int> per_face(6, 0);
  for (std::size_t t = 0; t < part.mesh_triangles.size(); ++t) {
    ASSERT_GE(part.triangle_face[t], 0);
    ASSERT_LT(part.triangle_face[t], 6);
    ++per_face[static_cast<std::size_t>(part.triangle_face[t])];
    for (const int v : part.mesh_triangles[t]) {
      ASSERT_GE(v, 0);
      ASSERT_LT(static_cast<std::size_t>(v), part.mesh_vertices.size());
    }
  }
  for (int n : per_face) EXPECT_GE(n, 2);
  // Every node lies on the box's surface.
  for (const Eigen::Vector3d& p : part.mesh_vertices) {
    const double on = std::min({std::abs(p.x() - 1), std::abs(p.x() - 11), std::abs(p.y() - 2), std::abs(p.y() - 22),
                                std::abs(p.z() - 3), std::abs(p.z() - 33)});
    EXPECT_LT(on, 1e-9) << p.transpose();
  }
  // read_cad gives the same faces; one face alone is meshed only on request; bad deflections.
  EXPECT_EQ(read_cad(dir.file("box.step")), part.faces);
  BSplineSurface plane;
  plane.degree_u = plane.degree_v = 1;
  plane.num_poles_u = plane.num_poles_v = 2;
  plane.knots_u = plane.knots_v = {0, 0, 1, 1};
  plane.poles_mm = {{0, 0, 0}, {0, 5, 0}, {5, 0, 0}, {5, 5, 0}};
  write_step(plane, dir.file("plane.step"));
  EXPECT_TRUE(read_cad_part(dir.file("plane.step"), 0.01).mesh_triangles.empty());
  EXPECT_GE(read_cad_part(dir.file("plane.step"), 0.01, true).mesh_triangles.size(), 2u);
  EXPECT_TRUE(read_cad_part(dir.file("box.step"), 0).mesh_triangles.empty());
  EXPECT_EQ(read_cad_part(dir.file("box.step"), 0).reversed, part.reversed);
  EXPECT_THROW(read_cad_part(dir.file("box.step"), -1), InputError);
  EXPECT_THROW(read_cad_part(dir.file("box.step"), std::nan("")), InputError);
}

// A curved outer wire comes back as a counter-clockwise polygon sampled on it.
TEST(Cad, CurvedBoundaryIsSampled) {
  TempDir dir;
  const gp_Circ circle(gp_Ax2(gp_Pnt(0, 0, 0), gp_Dir(0, 0, 1)), 5.0);
  const TopoDS_Wire wire = BRepBuilderAPI_MakeWire(BRepBuilderAPI_MakeEdge(circle).Edge()).Wire();
  occt_write_step(BRepBuilderAPI_MakeFace(gp_Pln(gp_Ax3()), wire).Face(), dir.file("disc.step"));
  const std::vector<BSplineSurface> read = read_step(dir.file("disc.step"));
  ASSERT_EQ(read.size(), 1u);
  const std::vector<Eigen::Vector2d>& b = read[0].boundary_uv;
  ASSERT_GE(b.size(), 16u);
  double twice_area = 0;
  for (std::size_t k = 0; k < b.size(); ++k) {
    EXPECT_NEAR(b[k].norm(), 5.0, 1e-6);  // the plane's (u,v) is its (x,y)
    twice_area += b[k].x() * b[(k + 1) % b.size()].y() - b[(k + 1) % b.size()].x() * b[k].y();
  }
  EXPECT_GT(twice_area, 0);
}

TEST(Cad, ReadCadSniffsContentWithoutAKnownExtension) {
  TempDir dir;
  write_step(bicubic(false), dir.file("a.step"));
  write_iges(bicubic(false), dir.file("a.iges"));
  fs::copy_file(dir.file("a.step"), dir.file("step.dat"));
  fs::copy_file(dir.file("a.iges"), dir.file("iges.dat"));
  EXPECT_EQ(read_cad(dir.file("step.dat")), read_step(dir.file("a.step")));
  EXPECT_EQ(read_cad(dir.file("iges.dat")), read_iges(dir.file("a.iges")));
}

TEST(Cad, UnreadableFilesAreInputErrors) {
  TempDir dir;
  const std::string missing = dir.file("missing.step");
  expect_input_error([&] { read_step(missing); }, missing, "no such file");
  expect_input_error([&] { read_iges(dir.file("missing.iges")); }, dir.file("missing.iges"), "no such file");
  expect_input_error([&] { read_cad(missing); }, missing, "no such file");
  expect_input_error([&] { read_step(dir.file("")); }, dir.file(""), "is a directory");

  const std::string empty = dir.file("empty.step");
  write_text(empty, "");
  expect_input_error([&] { read_step(empty); }, empty, "empty file");
  expect_input_error([&] { read_cad(empty); }, empty, "empty file");

  const std::string text = dir.file("notes.step");
  write_text(text, "x y z\n1 2 3\n");
  expect_input_error([&] { read_step(text); }, text, "not a STEP file");
  expect_input_error([&] { read_iges(text); }, text, "not an IGES file");
  const std::string text_dat = dir.file("notes.dat");
  write_text(text_dat, "x y z\n1 2 3\n");
  expect_input_error([&] { read_cad(text_dat); }, text_dat, "neither a STEP nor an IGES file");

  // Right magic, broken body; and a body cut short.
  const std::string broken = dir.file("broken.step");
  write_text(broken, "ISO-10303-21;\nHEADER;\nthis is not STEP\n");
  expect_input_error([&] { read_step(broken); }, broken, "not a readable STEP file: ");
  write_step(bicubic(false), dir.file("whole.step"));
  std::ifstream whole(dir.file("whole.step"));
  const std::string all((std::istreambuf_iterator<char>(whole)), {});
  const std::string cut = dir.file("cut.step");
  write_text(cut, all.substr(0, all.size() / 2));
  expect_input_error([&] { read_step(cut); }, cut, "not a readable STEP file: ");
  // An entity whose parameters cannot be read (one parameter short): Open CASCADE would create
  // it with unset fields and crash while transferring it (found by fuzzing); it is refused first.
  std::string short_entity = all;
  const std::string curve = "B_SPLINE_CURVE_WITH_KNOTS('',";
  const auto at = short_entity.find(curve);
  ASSERT_NE(at, std::string::npos) << "test bug: no " << curve << " in the written file";
  short_entity.replace(at, curve.size(), "B_SPLINE_CURVE_WITH_KNOTS(");
  const std::string unreadable = dir.file("unreadable.step");
  write_text(unreadable, short_entity);
  expect_input_error([&] { read_step(unreadable); }, unreadable, "cannot be read: entity #");
  expect_input_error([&] { read_step(unreadable); }, unreadable, "Count of Parameters is not 9 for b_spline_curve_with_knots");
  const std::string iges_like = dir.file("broken.iges");
  write_text(iges_like, std::string(72, ' ') + "S      1\n" + std::string(72, 'x') + "G      1\n");
  expect_input_error([&] { read_iges(iges_like); }, iges_like, "");
}

// Files on which Open CASCADE 7.6's parsers themselves crash (found by fuzzing): the read runs in
// a child process, and its crash is this process's InputError.
TEST(Cad, ReaderCrashesAreInputErrors) {
  const std::string corpus = std::string(PHOTOMILL_SOURCE_DIR) + "/tests/fuzz/corpus/";
  const std::string step = corpus + "step/crash-fffe3bbedb8eb1886502fca247e649dc7338184c";
  expect_input_error([&] { read_step(step); }, step, "malformed STEP file: Open CASCADE's reader crashed on it");
  const std::string iges = corpus + "iges/crash-66e16d2fa7ca5a0463b02841412aa106fe58511c";
  expect_input_error([&] { read_iges(iges); }, iges, "malformed IGES file: Open CASCADE's reader crashed on it");
  // A file the reader refuses before transferring (a parameter that cannot be read).
  const std::string refused = corpus + "step/crash-79050776544b7cdb1805831b0dbdfdd18e986b58";
  expect_input_error([&] { read_step(refused); }, refused, "cannot be read: entity #5");
}

TEST(Cad, FilesWithoutFacesAreInputErrors) {
  TempDir dir;
  const std::string path = dir.file("edge.step");
  occt_write_step(BRepBuilderAPI_MakeEdge(gp_Pnt(0, 0, 0), gp_Pnt(10, 0, 0)).Edge(), path);
  expect_input_error([&] { read_step(path); }, path, "no faces");
}

TEST(Cad, UnwritableSurfacesAndPathsAreInputErrors) {
  TempDir dir;
  const std::string nowhere = dir.file("no/such/dir/a.step");
  expect_input_error([&] { write_step(bicubic(false), nowhere); }, nowhere, "cannot create file");
  const std::string iges = dir.file("no/such/dir/a.iges");
  expect_input_error([&] { write_iges(bicubic(false), iges); }, iges, "cannot create file");

  BSplineSurface outside = trimmed();
  outside.boundary_uv[1].x() = 3.0;  // the u domain ends at 2.5
  const std::string path = dir.file("outside.step");
  expect_input_error([&] { write_step(outside, path); }, path, "outside the parameter domain");

  BSplineSurface huge = bicubic(false);
  huge.poles_mm[3].y() = -2e100;
  expect_input_error([&] { write_iges(huge, iges); }, iges, "exceeds 1e99");

  BSplineSurface invalid = bicubic(false);
  invalid.knots_u.pop_back();
  expect_input_error([&] { write_step(invalid, path); }, path, "knots_u");
}

}  // namespace
}  // namespace photomill
