// Point clouds: PLY (ASCII, binary little- and big-endian read; ASCII and binary little-endian
// written) with extra per-vertex scalar properties preserved, so CloudCompare and MeshLab show
// them as scalar fields; and plain "x y z" text (spaces, tabs or commas; extra columns ignored).
#pragma once

#include <cstddef>
#include <istream>
#include <ostream>
#include <string>
#include <string_view>
#include <vector>

#include <Eigen/Core>

namespace photomill {

enum class PlyScalar { Int8, UInt8, Int16, UInt16, Int32, UInt32, Float32, Float64 };

// One extra per-vertex property (anything but x, y, z): e.g. "views", "reproj_rms_px",
// "sigma_mm", "track_id", "red". Values are held as double, which represents every PLY scalar
// type exactly; `type` is the type written back.
struct PointProperty {
  std::string name;
  PlyScalar type = PlyScalar::Float64;
  std::vector<double> values;  // one per point
  bool operator==(const PointProperty&) const = default;
};

struct PointCloud {
  std::vector<Eigen::Vector3d> points_mm;     // world frame, mm
  std::vector<PointProperty> properties;      // in file order; each has points_mm.size() values
  PlyScalar xyz_type = PlyScalar::Float64;    // type of x, y, z written to PLY
  // The unit of points_mm (and of every *_mm property): "mm", or "arbitrary" for a reconstruction
  // without any datum (no control points, scale bars or known poses: its first baseline is 1).
  // PLY keeps it in the header line "comment photomill point cloud, units ..."; a file without
  // that line is in mm.
  std::string units = "mm";

  // The property `name`, else "scalar_" + name (the form CloudCompare loads as a scalar field,
  // which triangulate writes: find("sigma_mm") finds scalar_sigma_mm in new files and sigma_mm
  // in older ones); nullptr when neither is there.
  const PointProperty* find(std::string_view name) const;
  // Adds a property filled with zeros (or returns the existing one of that name).
  PointProperty& add_property(const std::string& name, PlyScalar type);
  bool operator==(const PointCloud&) const = default;
};

enum class PlyEncoding { Ascii, BinaryLittleEndian };

struct PointCloudLimits {
  // Lines of text formats longer than this are rejected.
  std::size_t max_line_bytes = 1 << 20;
  // PLY header size limit.
  std::size_t max_header_bytes = 1 << 16;
};

// Reads the "vertex" element of a PLY file (other elements are skipped). Counts in the header are
// never trusted for allocation: a truncated file is reported with how many vertices it had.
PointCloud read_ply(std::istream& in, const std::string& source, PointCloudLimits limits = {});
void write_ply(std::ostream& out, const PointCloud& cloud, PlyEncoding encoding,
               const std::string& comment = "");

// Plain text: one point per line, the first three numbers are x y z in mm.
PointCloud read_xyz(std::istream& in, const std::string& source, PointCloudLimits limits = {});
void write_xyz(std::ostream& out, const PointCloud& cloud);

// PLY if the input starts with "ply", otherwise plain text.
PointCloud read_point_cloud(std::istream& in, const std::string& source,
                            PointCloudLimits limits = {});

}  // namespace photomill
