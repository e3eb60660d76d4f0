#include "surfmap/mesh/mesh_io.h"

#include <OpenMesh/Core/IO/IOManager.hh>
#include <OpenMesh/Core/IO/Options.hh>
#include <OpenMesh/Core/IO/importer/BaseImporter.hh>

#include <algorithm>
#include <cctype>
#include <cstdio>
#include <filesystem>
#include <fstream>
#include <iomanip>
#include <sstream>
#include <unistd.h>

#include "surfmap/error.h"

// OpenMesh's reader modules (OBJ, OFF, PLY, STL) register themselves through
// static objects in this header; including it once here is enough.
#include <OpenMesh/Core/IO/MeshIO.hh>

namespace surfmap {
namespace {

namespace OM = OpenMesh;

// Collects what OpenMesh's readers parse as a raw polygon soup. The stock
// importer builds a halfedge mesh and silently drops faces it cannot insert
// (non-manifold, repeated indices); intake must see those to report them.
class SoupImporter : public OM::IO::BaseImporter {
 public:
  std::vector<Eigen::Vector3d> points;
  std::vector<std::vector<int>> polygons;

  OM::VertexHandle add_vertex(const OM::Vec3f& p) override { return add_vertex(OM::Vec3d(p)); }
  OM::VertexHandle add_vertex(const OM::Vec3d& p) override {
    points.emplace_back(p[0], p[1], p[2]);
    return OM::VertexHandle(static_cast<int>(points.size()) - 1);
  }
  OM::VertexHandle add_vertex() override { return add_vertex(OM::Vec3d(0, 0, 0)); }
  OM::HalfedgeHandle add_edge(OM::VertexHandle, OM::VertexHandle) override { return OM::HalfedgeHandle(); }
  OM::FaceHandle add_face(const VHandles& idx) override {
    std::vector<int> poly;
    poly.reserve(idx.size());
    for (const auto& vh : idx) poly.push_back(vh.idx());
    polygons.push_back(std::move(poly));
    return OM::FaceHandle(static_cast<int>(polygons.size()) - 1);
  }
  OM::FaceHandle add_face(OM::HalfedgeHandle) override { return OM::FaceHandle(); }
  void add_face_texcoords(OM::FaceHandle, OM::VertexHandle, const std::vector<OM::Vec2f>&) override {}
  void add_face_texcoords(OM::FaceHandle, OM::VertexHandle, const std::vector<OM::Vec3f>&) override {}
  void set_face_texindex(OM::FaceHandle, int) override {}
  void set_point(OM::VertexHandle vh, const OM::Vec3f& p) override {
    if (vh.idx() >= 0 && vh.idx() < static_cast<int>(points.size()))
      points[vh.idx()] = Eigen::Vector3d(p[0], p[1], p[2]);
  }
  void set_halfedge(OM::VertexHandle, OM::HalfedgeHandle) override {}
  void set_normal(OM::VertexHandle, const OM::Vec3f&) override {}
  void set_normal(OM::VertexHandle, const OM::Vec3d&) override {}
  void set_color(OM::VertexHandle, const OM::Vec3uc&) override {}
  void set_color(OM::VertexHandle, const OM::Vec4uc&) override {}
  void set_color(OM::VertexHandle, const OM::Vec3f&) override {}
  void set_color(OM::VertexHandle, const OM::Vec4f&) override {}
  void set_texcoord(OM::VertexHandle, const OM::Vec2f&) override {}
  void set_status(OM::VertexHandle, const OM::Attributes::StatusInfo&) override {}
  void set_next(OM::HalfedgeHandle, OM::HalfedgeHandle) override {}
  void set_face(OM::HalfedgeHandle, OM::FaceHandle) override {}
  void request_face_texcoords2D() override {}
  void set_texcoord(OM::HalfedgeHandle, const OM::Vec2f&) override {}
  void set_texcoord(OM::VertexHandle, const OM::Vec3f&) override {}
  void set_texcoord(OM::HalfedgeHandle, const OM::Vec3f&) override {}
  void set_status(OM::HalfedgeHandle, const OM::Attributes::StatusInfo&) override {}
  void set_color(OM::EdgeHandle, const OM::Vec3uc&) override {}
  void set_color(OM::EdgeHandle, const OM::Vec4uc&) override {}
  void set_color(OM::EdgeHandle, const OM::Vec3f&) override {}
  void set_color(OM::EdgeHandle, const OM::Vec4f&) override {}
  void set_status(OM::EdgeHandle, const OM::Attributes::StatusInfo&) override {}
  void set_normal(OM::FaceHandle, const OM::Vec3f&) override {}
  void set_normal(OM::FaceHandle, const OM::Vec3d&) override {}
  void set_color(OM::FaceHandle, const OM::Vec3uc&) override {}
  void set_color(OM::FaceHandle, const OM::Vec4uc&) override {}
  void set_color(OM::FaceHandle, const OM::Vec3f&) override {}
  void set_color(OM::FaceHandle, const OM::Vec4f&) override {}
  void set_status(OM::FaceHandle, const OM::Attributes::StatusInfo&) override {}
  void add_texture_information(int, std::string) override {}
  size_t n_vertices() const override { return points.size(); }
  size_t n_faces() const override { return polygons.size(); }
  size_t n_edges() const override { return 0; }
};

// Writes through a temporary file in the same directory and renames it over
// the destination, so readers never see a half-written file.
template <class WriteFn>
void write_atomically(const std::string& path, WriteFn&& write) {
  namespace fs = std::filesystem;
  const fs::path dest(path);
  const fs::path tmp = dest.parent_path() /
                       ("." + dest.filename().string() + ".tmp" + std::to_string(::getpid()));
  {
    std::ofstream out(tmp, std::ios::binary);
    if (!out) throw Error("cannot write '" + path + "': cannot create a file in its directory");
    write(out);
    out.flush();
    if (!out) {
      out.close();
      std::error_code ec;
      fs::remove(tmp, ec);
      throw Error("writing '" + path + "' failed (disk full?)");
    }
  }
  std::error_code ec;
  fs::rename(tmp, dest, ec);
  if (ec) {
    fs::remove(tmp, ec);
    throw Error("cannot write '" + path + "': " + ec.message());
  }
}

}  // namespace

PolygonSoup read_polygon_soup(const std::string& path) {
  namespace fs = std::filesystem;
  std::error_code ec;
  if (!fs::exists(path, ec)) throw InputError("mesh file '" + path + "' does not exist");
  if (fs::is_directory(path, ec)) throw InputError("'" + path + "' is a directory, not a mesh file");
  std::string ext = fs::path(path).extension().string();
  std::transform(ext.begin(), ext.end(), ext.begin(), [](unsigned char c) { return std::tolower(c); });
  if (ext != ".obj" && ext != ".off" && ext != ".ply" && ext != ".stl")
    throw InputError("'" + path + "': unknown mesh format (use .obj, .off, .ply or .stl)");
  SoupImporter importer;
  OM::IO::Options opt;
  // OpenMesh's readers print their own complaints to std::cerr via omerr();
  // we report problems ourselves, so silence them for the duration.
  const bool err_was_enabled = ::omerr().is_enabled(), log_was_enabled = ::omlog().is_enabled();
  ::omerr().disable();
  ::omlog().disable();
  const bool ok = OM::IO::IOManager().read(path, importer, opt);
  if (err_was_enabled) ::omerr().enable();
  if (log_was_enabled) ::omlog().enable();
  if (!ok) throw InputError("'" + path + "' could not be parsed as a mesh file");
  PolygonSoup soup;
  soup.V.resize(static_cast<int>(importer.points.size()), 3);
  for (size_t i = 0; i < importer.points.size(); ++i) soup.V.row(i) = importer.points[i].transpose();
  soup.polygons = std::move(importer.polygons);
  if (soup.polygons.empty()) throw InputError("'" + path + "' contains no faces");
  return soup;
}

void write_obj(const std::string& path, const RowMatrixX3d& V, const RowMatrixX3i& F) {
  write_atomically(path, [&](std::ostream& out) {
    out << "# written by surfmap\n" << std::setprecision(17);
    for (int i = 0; i < V.rows(); ++i) out << "v " << V(i, 0) << ' ' << V(i, 1) << ' ' << V(i, 2) << '\n';
    for (int f = 0; f < F.rows(); ++f)
      out << "f " << F(f, 0) + 1 << ' ' << F(f, 1) + 1 << ' ' << F(f, 2) + 1 << '\n';
  });
}

void write_text_file(const std::string& path, const std::string& text) {
  write_atomically(path, [&](std::ostream& out) { out << text; });
}

}  // namespace surfmap
