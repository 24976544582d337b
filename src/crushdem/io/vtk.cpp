// VTK XML PolyData and .pvd writers, see vtk.hpp. Every array goes to the appended block as
// "raw" bytes preceded by its size in bytes (UInt64, header_type), which is what ParaView and
// the VTK readers expect for encoding="raw".
#include "crushdem/io/vtk.hpp"

#include <algorithm>
#include <bit>
#include <cmath>
#include <cstdio>
#include <cstring>
#include <iterator>
#include <string_view>
#include <unordered_map>
#include <utility>

#include "crushdem/core/error.hpp"
#include "crushdem/io/output.hpp"

namespace crushdem {

static_assert(std::endian::native == std::endian::little,
              "the .vtp files declare byte_order=\"LittleEndian\"");

namespace {

/// Which arrays of a PolyData piece go into which section.
enum class Section { PointData, CellData, Points, Verts, Lines, Polys };

class PolyData {
 public:
  PolyData(std::size_t points, std::size_t verts, std::size_t lines, std::size_t polys)
      : points_(points), verts_(verts), lines_(lines), polys_(polys) {}

  template <class T>
  void add(Section s, const char* vtk_type, const std::string& name, int components,
           const std::vector<T>& values) {
    const std::uint64_t bytes = values.size() * sizeof(T);
    std::string& xml = xml_[static_cast<int>(s)];
    xml += "      <DataArray type=\"" + std::string(vtk_type) + "\" Name=\"" + name +
           "\" NumberOfComponents=\"" + std::to_string(components) +
           "\" format=\"appended\" offset=\"" + std::to_string(blob_.size()) + "\"/>\n";
    blob_.append(reinterpret_cast<const char*>(&bytes), sizeof bytes);
    blob_.append(reinterpret_cast<const char*>(values.data()), bytes);
  }

  void write(const std::string& path) const {
    std::string out =
        "<?xml version=\"1.0\"?>\n"
        "<VTKFile type=\"PolyData\" version=\"1.0\" byte_order=\"LittleEndian\" "
        "header_type=\"UInt64\">\n  <PolyData>\n    <Piece NumberOfPoints=\"" +
        std::to_string(points_) + "\" NumberOfVerts=\"" + std::to_string(verts_) +
        "\" NumberOfLines=\"" + std::to_string(lines_) +
        "\" NumberOfStrips=\"0\" NumberOfPolys=\"" + std::to_string(polys_) + "\">\n";
    static const char* const kTags[] = {"PointData", "CellData", "Points",
                                        "Verts",     "Lines",    "Polys"};
    for (int s = 0; s < 6; ++s) {
      if (xml_[s].empty()) continue;
      out += "     <" + std::string(kTags[s]) + ">\n" + xml_[s] + "     </" + kTags[s] + ">\n";
    }
    out += "    </Piece>\n  </PolyData>\n  <AppendedData encoding=\"raw\">\n   _";
    out += blob_;
    out += "\n  </AppendedData>\n</VTKFile>\n";
    write_file_atomically(path, out);
  }

 private:
  std::size_t points_, verts_, lines_, polys_;
  std::string xml_[6];
  std::string blob_;
};

std::vector<std::int64_t> iota(std::size_t n, std::int64_t step = 1, std::int64_t first = 0) {
  std::vector<std::int64_t> v(n);
  for (std::size_t i = 0; i < n; ++i) v[i] = first + static_cast<std::int64_t>(i) * step;
  return v;
}

std::vector<double> interleave(const std::vector<double>& a, const std::vector<double>& b,
                               const std::vector<double>& c) {
  std::vector<double> v(3 * a.size());
  for (std::size_t i = 0; i < a.size(); ++i) {
    v[3 * i] = a[i];
    v[3 * i + 1] = b[i];
    v[3 * i + 2] = c[i];
  }
  return v;
}

std::string xml_escape(const std::string& s) {
  static constexpr std::pair<char, std::string_view> kEntities[] = {
      {'&', "&amp;"}, {'<', "&lt;"}, {'>', "&gt;"}, {'"', "&quot;"}};
  std::string out;
  for (char c : s) {
    const auto* entity = std::find_if(std::begin(kEntities), std::end(kEntities),
                                      [c](const auto& e) { return e.first == c; });
    if (entity != std::end(kEntities)) {
      out += entity->second;
    } else {
      out += c;
    }
  }
  return out;
}

}  // namespace

void write_vtp_particles(const std::string& path, const ParticleStore& p,
                         const std::vector<double>& fx, const std::vector<double>& fy,
                         const std::vector<double>& fz) {
  const std::size_t n = p.size();
  PolyData vtp(n, n, 0, 0);
  std::vector<std::int64_t> id(n), parent(n);
  for (std::size_t i = 0; i < n; ++i) {
    id[i] = static_cast<std::int64_t>(p.id[i]);
    parent[i] = p.parent[i] == kNoParent ? -1 : static_cast<std::int64_t>(p.parent[i]);
  }
  vtp.add(Section::PointData, "Int64", "id", 1, id);
  vtp.add(Section::PointData, "Int64", "parent_id", 1, parent);
  vtp.add(Section::PointData, "Float64", "radius", 1, p.radius);
  vtp.add(Section::PointData, "Float64", "velocity", 3, interleave(p.vx, p.vy, p.vz));
  vtp.add(Section::PointData, "Float64", "angular_velocity", 3, interleave(p.wx, p.wy, p.wz));
  if (fx.size() == n) vtp.add(Section::PointData, "Float64", "force", 3, interleave(fx, fy, fz));
  for (std::size_t k = 0; k < p.field_names().size(); ++k) {
    vtp.add(Section::PointData, "Float64", xml_escape(p.field_names()[k]), 1, p.field(k));
  }
  vtp.add(Section::Points, "Float64", "Points", 3, interleave(p.x, p.y, p.z));
  vtp.add(Section::Verts, "Int64", "connectivity", 1, iota(n));
  vtp.add(Section::Verts, "Int64", "offsets", 1, iota(n, 1, 1));
  vtp.write(path);
}

void write_vtp_contacts(const std::string& path, const ParticleStore& p,
                        const std::vector<ContactRecord>& contacts) {
  std::unordered_map<ParticleId, std::size_t> index;
  index.reserve(p.size());
  for (std::size_t i = 0; i < p.size(); ++i) index.emplace(p.id[i], i);
  const std::size_t n = contacts.size();
  std::vector<double> points;
  points.reserve(6 * n);
  std::vector<double> fn(n), delta(n), ft(3 * n), ft_mag(n), normal(3 * n);
  std::vector<std::uint8_t> wall(n);
  std::vector<std::int64_t> id_i(n), id_j(n);
  for (std::size_t c = 0; c < n; ++c) {
    const ContactRecord& r = contacts[c];
    const auto it = index.find(r.id_i);
    if (it == index.end())
      throw RuntimeFailure("contact of unknown grain " + std::to_string(r.id_i));
    const std::size_t i = it->second;
    points.insert(points.end(), {p.x[i], p.y[i], p.z[i]});
    if (r.is_wall) {  // the contact point: the grain's surface, half the overlap into the wall
      const double reach = p.radius[i] - 0.5 * r.delta;
      points.insert(points.end(), {p.x[i] + reach * r.normal.x, p.y[i] + reach * r.normal.y,
                                   p.z[i] + reach * r.normal.z});
    } else {
      const auto jt = index.find(r.id_j);
      if (jt == index.end())
        throw RuntimeFailure("contact of unknown grain " + std::to_string(r.id_j));
      const std::size_t j = jt->second;
      points.insert(points.end(), {p.x[j], p.y[j], p.z[j]});
    }
    fn[c] = r.F_n;
    delta[c] = r.delta;
    wall[c] = r.is_wall ? 1 : 0;
    id_i[c] = static_cast<std::int64_t>(r.id_i);
    id_j[c] = static_cast<std::int64_t>(r.id_j);
    ft[3 * c] = r.F_t.x;
    ft[3 * c + 1] = r.F_t.y;
    ft[3 * c + 2] = r.F_t.z;
    ft_mag[c] = norm(r.F_t);
    normal[3 * c] = r.normal.x;
    normal[3 * c + 1] = r.normal.y;
    normal[3 * c + 2] = r.normal.z;
  }
  PolyData vtp(2 * n, 0, n, 0);
  vtp.add(Section::CellData, "Float64", "normal_force", 1, fn);
  vtp.add(Section::CellData, "Float64", "tangential_force", 3, ft);
  vtp.add(Section::CellData, "Float64", "tangential_force_magnitude", 1, ft_mag);
  vtp.add(Section::CellData, "Float64", "normal", 3, normal);
  vtp.add(Section::CellData, "Float64", "overlap", 1, delta);
  vtp.add(Section::CellData, "UInt8", "is_wall", 1, wall);
  vtp.add(Section::CellData, "Int64", "id_i", 1, id_i);
  vtp.add(Section::CellData, "Int64", "id_j", 1, id_j);
  vtp.add(Section::Points, "Float64", "Points", 3, points);
  vtp.add(Section::Lines, "Int64", "connectivity", 1, iota(2 * n));
  vtp.add(Section::Lines, "Int64", "offsets", 1, iota(n, 2, 2));
  vtp.write(path);
}

void write_vtp_box(const std::string& path, const double b[6]) {
  std::vector<double> corners;
  for (int k = 0; k < 8; ++k) {
    corners.insert(corners.end(), {b[(k & 1) ? 1 : 0], b[(k & 2) ? 3 : 2], b[(k & 4) ? 5 : 4]});
  }
  PolyData vtp(8, 0, 0, 6);
  vtp.add(Section::Points, "Float64", "Points", 3, corners);
  vtp.add(Section::Polys, "Int64", "connectivity", 1,
          std::vector<std::int64_t>{0, 2, 6, 4, 1, 3, 7, 5, 0, 1, 5, 4,
                                    2, 3, 7, 6, 0, 1, 3, 2, 4, 5, 7, 6});
  vtp.add(Section::Polys, "Int64", "offsets", 1, iota(6, 4, 4));
  vtp.write(path);
}

namespace {

/// The surfaces of the bodies as polygons: points, each polygon's point indices, its body and
/// part.
struct BodyMesh {
  std::vector<double> points;
  std::vector<std::int64_t> connectivity, offsets, body, part;

  std::int64_t point(Vec3 p) {
    points.insert(points.end(), {p.x, p.y, p.z});
    return static_cast<std::int64_t>(points.size() / 3 - 1);
  }
  void polygon(std::initializer_list<std::int64_t> ids, int k, int j) {
    connectivity.insert(connectivity.end(), ids);
    offsets.push_back(static_cast<std::int64_t>(connectivity.size()));
    body.push_back(k);
    part.push_back(j);
  }
};

/// Two unit vectors normal to the unit vector a and to each other.
std::pair<Vec3, Vec3> normal_pair(Vec3 a) {
  const Vec3 t = std::fabs(a.x) < 0.9 ? Vec3{1.0, 0.0, 0.0} : Vec3{0.0, 1.0, 0.0};
  Vec3 e1 = t - dot(t, a) * a;
  e1 = (1.0 / norm(e1)) * e1;
  return {e1, cross(a, e1)};
}

constexpr int kSegments = 48;  // around a circle

}  // namespace

void write_vtp_bodies(const std::string& path, const Walls& walls) {
  BodyMesh m;
  double extent = 0.0;  // an infinite plane is drawn as a square of the box's diagonal
  for (int a = 0; a < 3; ++a) {
    const double L = walls.position(2 * a + 1) - walls.position(2 * a);
    extent += L * L;
  }
  extent = std::sqrt(extent);
  for (int k = kNumWalls; k < walls.size(); ++k) {
    const BodyShape& b = walls.shape(k);
    const double q = walls.position(k);
    for (int j = 0; j < b.parts; ++j) {
      const BodyPart s = placed_part(b.part[j], q, b.motion, b.dilate);
      const Vec3 o = s.origin;
      const double R = s.radius;
      const auto [e1, e2] = normal_pair(s.axis);
      const auto ring = [&, e1 = e1, e2 = e2](Vec3 centre, double radius) {
        const std::int64_t first = static_cast<std::int64_t>(m.points.size() / 3);
        for (int i = 0; i < kSegments; ++i) {
          const double phi = 2.0 * kPi * i / kSegments;
          m.point(centre + radius * (std::cos(phi) * e1 + std::sin(phi) * e2));
        }
        return first;
      };
      const auto next = [](std::int64_t first, int i) { return first + (i + 1) % kSegments; };
      switch (s.shape) {
        case Shape::AxisPlane: break;
        case Shape::Plane: {
          const std::int64_t c0 = m.point(o - extent * e1 - extent * e2);
          const std::int64_t c1 = m.point(o + extent * e1 - extent * e2);
          const std::int64_t c2 = m.point(o + extent * e1 + extent * e2);
          const std::int64_t c3 = m.point(o - extent * e1 + extent * e2);
          m.polygon({c0, c1, c2, c3}, k, j);
          break;
        }
        case Shape::Disk: {
          const std::int64_t c = m.point(o), r0 = ring(o, R);
          for (int i = 0; i < kSegments; ++i) m.polygon({c, r0 + i, next(r0, i)}, k, j);
          break;
        }
        case Shape::CylinderInside:
        case Shape::CylinderOutside: {
          const std::int64_t r0 = ring(o, R), r1 = ring(o + s.length * s.axis, R);
          for (int i = 0; i < kSegments; ++i) {
            m.polygon({r0 + i, next(r0, i), next(r1, i), r1 + i}, k, j);
          }
          break;
        }
        case Shape::Cone: {
          const std::int64_t apex = m.point(o), r0 = ring(o + s.length * s.axis, R);
          for (int i = 0; i < kSegments; ++i) m.polygon({apex, r0 + i, next(r0, i)}, k, j);
          break;
        }
      }
    }
  }
  PolyData vtp(m.points.size() / 3, 0, 0, m.offsets.size());
  vtp.add(Section::CellData, "Int64", "body", 1, m.body);
  vtp.add(Section::CellData, "Int64", "part", 1, m.part);
  vtp.add(Section::Points, "Float64", "Points", 3, m.points);
  vtp.add(Section::Polys, "Int64", "connectivity", 1, m.connectivity);
  vtp.add(Section::Polys, "Int64", "offsets", 1, m.offsets);
  vtp.write(path);
}

void write_pvd(const std::string& path, const std::vector<PvdEntry>& entries) {
  std::string out =
      "<?xml version=\"1.0\"?>\n<VTKFile type=\"Collection\" version=\"1.0\" "
      "byte_order=\"LittleEndian\">\n  <Collection>\n";
  for (const PvdEntry& e : entries) {
    out += "    <DataSet timestep=\"" + format_double(e.time) + "\" part=\"0\" file=\"" +
           xml_escape(e.file) + "\"/>\n";
  }
  out += "  </Collection>\n</VTKFile>\n";
  write_file_atomically(path, out);
}

}  // namespace crushdem
