#include "surfmap/mesh/mesh_io.h"

#include <OpenMesh/Core/IO/IOManager.hh>
#include <OpenMesh/Core/IO/Options.hh>
#include <OpenMesh/Core/IO/importer/BaseImporter.hh>

#include <algorithm>
#include <cctype>
#include <cstdint>
#include <cstring>
#include <cerrno>
#include <cstdlib>
#include <limits>
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

// ASCII OFF, read here rather than by OpenMesh: its OFF reader trusts the
// header's counts and each face's vertex count, so a corrupt number makes it
// loop for billions of reads or allocate gigabytes (found by fuzzing,
// tests/fuzz/corpus/findings). Here every count is bounded by what the file
// actually contains. Variants [ST][C][N][4]OFF: the first three numbers of a
// vertex line are its position (extra columns: normals, colours, texture
// coordinates); a face line is n, then n indices, then optional colour.
class OffReader {
 public:
  OffReader(std::istream& in, std::string path) : in_(in), path_(std::move(path)) {}

  PolygonSoup read() {
    std::vector<std::string> tok = next_line("the header");
    if (!tok.empty() && tok[0].size() >= 3 && tok[0].compare(tok[0].size() - 3, 3, "OFF") == 0) {
      const std::string kw = tok[0];
      if (kw.find('n') != std::string::npos) fail("the nOFF (any-dimension) variant is not supported");
      if (std::find(tok.begin(), tok.end(), "BINARY") != tok.end())
        fail("binary OFF is not supported (convert it to ASCII OFF, OBJ or PLY)");
      tok.erase(tok.begin());
      if (tok.empty()) tok = next_line("the counts line");
    }
    if (tok.size() < 2) fail("the counts line needs the numbers of vertices and faces");
    const long long nv = integer(tok[0], "vertex count"), nf = integer(tok[1], "face count");
    PolygonSoup soup;
    std::vector<Eigen::Vector3d> points;
    for (long long v = 0; v < nv; ++v) {
      const auto t = next_line("vertex " + std::to_string(v) + " of " + std::to_string(nv));
      if (t.size() < 3) fail("vertex " + std::to_string(v) + " has fewer than 3 coordinates");
      points.emplace_back(real(t[0]), real(t[1]), real(t[2]));
    }
    for (long long f = 0; f < nf; ++f) {
      const auto t = next_line("face " + std::to_string(f) + " of " + std::to_string(nf));
      const long long n = integer(t[0], "vertex count of face " + std::to_string(f));
      if (n + 1 > static_cast<long long>(t.size()))
        fail("face " + std::to_string(f) + " announces " + std::to_string(n) + " vertices but lists " +
             std::to_string(t.size() - 1));
      std::vector<int> poly;
      for (long long k = 1; k <= n; ++k) {
        const long long idx = integer(t[k], "vertex index in face " + std::to_string(f));
        if (idx > std::numeric_limits<int>::max())
          fail("face " + std::to_string(f) + " refers to vertex " + t[k] + ", out of range");
        poly.push_back(static_cast<int>(idx));
      }
      soup.polygons.push_back(std::move(poly));
    }
    soup.V.resize(static_cast<int>(points.size()), 3);
    for (size_t i = 0; i < points.size(); ++i) soup.V.row(static_cast<int>(i)) = points[i].transpose();
    return soup;
  }

 private:
  std::istream& in_;
  std::string path_;
  long long line_no_ = 0;

  [[noreturn]] void fail(const std::string& what) const {
    throw InputError("'" + path_ + "' line " + std::to_string(line_no_) + ": " + what);
  }
  // The next line with content, split at whitespace; '#' starts a comment.
  std::vector<std::string> next_line(const std::string& what) {
    std::string line;
    while (std::getline(in_, line)) {
      ++line_no_;
      const auto hash = line.find('#');
      if (hash != std::string::npos) line.resize(hash);
      std::istringstream ls(line);
      std::vector<std::string> tok;
      for (std::string w; ls >> w;) tok.push_back(w);
      if (!tok.empty()) return tok;
    }
    fail("the file ends before " + what);
  }
  long long integer(const std::string& w, const std::string& what) const {
    errno = 0;
    char* end = nullptr;
    const long long v = std::strtoll(w.c_str(), &end, 10);
    if (end == w.c_str() || *end != '\0' || errno == ERANGE || v < 0)
      fail(what + " '" + w.substr(0, 40) + "' is not a non-negative integer");
    return v;
  }
  double real(const std::string& w) const {
    char* end = nullptr;
    const double v = std::strtod(w.c_str(), &end);
    if (end == w.c_str() || *end != '\0') fail("'" + w.substr(0, 40) + "' is not a number");
    return v;  // NaN and Inf pass: intake names the vertex
  }
};

// PLY, read here rather than by OpenMesh: its header loop never ends on a
// truncated header, and its ASCII reader trusts each face's list count
// (found by fuzzing). ASCII and binary (little/big endian); positions from
// the vertex element's x, y, z; polygons from the face element's
// vertex_indices (or vertex_index) list; every other element and property
// is read past. Counts are bounded by the bytes that are actually there.
class PlyReader {
 public:
  PlyReader(std::istream& in, std::string path) : in_(in), path_(std::move(path)) {}

  PolygonSoup read() {
    parse_header();
    PolygonSoup soup;
    std::vector<Eigen::Vector3d> points;
    for (const Element& el : elements_) {
      const bool is_vertex = el.name == "vertex", is_face = el.name == "face";
      for (long long i = 0; i < el.count; ++i) {
        Eigen::Vector3d p(0, 0, 0);
        std::vector<int> poly;
        for (const Property& pr : el.props) {
          if (pr.list) {
            const double n = scalar(pr.count_type);
            if (!(n >= 0 && n == std::floor(n) && n <= 1e6))
              fail(el.name + " " + std::to_string(i) + ": list length " + std::to_string(n) + " is invalid");
            const bool keep = is_face && (pr.name == "vertex_indices" || pr.name == "vertex_index");
            for (long long k = 0; k < static_cast<long long>(n); ++k) {
              const double v = scalar(pr.type);
              if (!keep) continue;
              if (!(v == std::floor(v) && std::abs(v) <= std::numeric_limits<int>::max()))
                fail("face " + std::to_string(i) + ": vertex index " + std::to_string(v) + " is not an index");
              poly.push_back(static_cast<int>(v));
            }
          } else {
            const double v = scalar(pr.type);
            if (is_vertex && pr.name == "x") p.x() = v;
            if (is_vertex && pr.name == "y") p.y() = v;
            if (is_vertex && pr.name == "z") p.z() = v;
          }
        }
        if (is_vertex) points.push_back(p);
        if (is_face) soup.polygons.push_back(std::move(poly));
      }
    }
    soup.V.resize(static_cast<int>(points.size()), 3);
    for (size_t i = 0; i < points.size(); ++i) soup.V.row(static_cast<int>(i)) = points[i].transpose();
    return soup;
  }

 private:
  struct Property {
    std::string name, type, count_type;
    bool list = false;
  };
  struct Element {
    std::string name;
    long long count = 0;
    std::vector<Property> props;
  };
  std::istream& in_;
  std::string path_;
  std::vector<Element> elements_;
  enum class Format { Ascii, Little, Big } format_ = Format::Ascii;

  [[noreturn]] void fail(const std::string& what) const { throw InputError("'" + path_ + "' (PLY): " + what); }

  static int type_size(const std::string& t) {
    if (t == "char" || t == "uchar" || t == "int8" || t == "uint8") return 1;
    if (t == "short" || t == "ushort" || t == "int16" || t == "uint16") return 2;
    if (t == "int" || t == "uint" || t == "float" || t == "int32" || t == "uint32" || t == "float32") return 4;
    if (t == "double" || t == "float64") return 8;
    return 0;
  }

  void parse_header() {
    std::string line;
    int line_no = 0;
    auto bad = [&](const std::string& what) { fail("header line " + std::to_string(line_no) + ": " + what); };
    bool have_format = false;
    while (std::getline(in_, line)) {
      ++line_no;
      if (line_no > 10000) bad("no end_header in the first 10000 lines");
      if (!line.empty() && line.back() == '\r') line.pop_back();
      std::istringstream ls(line);
      std::vector<std::string> t;
      for (std::string w; ls >> w;) t.push_back(w);
      if (line_no == 1) {
        if (t.size() != 1 || t[0] != "ply") bad("the file does not start with 'ply'");
        continue;
      }
      if (t.empty()) bad("empty header line");
      const std::string& k = t[0];
      if (k == "comment" || k == "obj_info") continue;
      if (k == "end_header") {
        if (!have_format) bad("end_header before the format line");
        if (!elements_.empty() && elements_.back().props.empty() && elements_.back().count > 0)
          bad("element '" + elements_.back().name.substr(0, 40) + "' has no properties");
        return;
      }
      if (k == "format") {
        if (t.size() != 3) bad("malformed format line");
        if (t[1] == "ascii") format_ = Format::Ascii;
        else if (t[1] == "binary_little_endian") format_ = Format::Little;
        else if (t[1] == "binary_big_endian") format_ = Format::Big;
        else bad("unknown format '" + t[1].substr(0, 40) + "'");
        have_format = true;
      } else if (k == "element") {
        if (t.size() != 3) bad("an element line needs a name and a count");
        errno = 0;
        char* end = nullptr;
        const long long n = std::strtoll(t[2].c_str(), &end, 10);
        if (*end != '\0' || end == t[2].c_str() || n < 0 || errno == ERANGE || n > std::numeric_limits<int>::max())
          bad("element count '" + t[2].substr(0, 40) + "' is not a non-negative integer");
        if (!elements_.empty() && elements_.back().props.empty() && elements_.back().count > 0)
          bad("element '" + elements_.back().name.substr(0, 40) + "' has no properties");
        elements_.push_back({t[1], n, {}});
      } else if (k == "property") {
        if (elements_.empty()) bad("a property before any element");
        Property pr;
        if (t.size() == 3 && type_size(t[1]) > 0) {
          pr.type = t[1];
          pr.name = t[2];
        } else if (t.size() == 5 && t[1] == "list" && type_size(t[2]) > 0 && type_size(t[3]) > 0) {
          pr.list = true;
          pr.count_type = t[2];
          pr.type = t[3];
          pr.name = t[4];
        } else {
          bad("malformed property line '" + line.substr(0, 60) + "'");
        }
        elements_.back().props.push_back(pr);
      } else {
        bad("unknown header keyword '" + k.substr(0, 40) + "'");
      }
    }
    fail("the file ends before end_header");
  }

  // One value of type t: a whitespace-separated token (ASCII) or its bytes.
  double scalar(const std::string& t) {
    if (format_ == Format::Ascii) {
      std::string w;
      if (!(in_ >> w)) fail("the file ends in the middle of the data");
      char* end = nullptr;
      const double v = std::strtod(w.c_str(), &end);
      if (end == w.c_str() || *end != '\0') fail("'" + w.substr(0, 40) + "' is not a number");
      return v;
    }
    unsigned char b[8];
    const int n = type_size(t);
    if (!in_.read(reinterpret_cast<char*>(b), n)) fail("the file ends in the middle of the data");
    const bool host_little = [] {
      const uint16_t x = 1;
      unsigned char c;
      std::memcpy(&c, &x, 1);
      return c == 1;
    }();
    if ((format_ == Format::Little) != host_little) std::reverse(b, b + n);
    auto as = [&](auto v) {
      std::memcpy(&v, b, sizeof v);
      return static_cast<double>(v);
    };
    if (t == "char" || t == "int8") return as(int8_t());
    if (t == "uchar" || t == "uint8") return as(uint8_t());
    if (t == "short" || t == "int16") return as(int16_t());
    if (t == "ushort" || t == "uint16") return as(uint16_t());
    if (t == "int" || t == "int32") return as(int32_t());
    if (t == "uint" || t == "uint32") return as(uint32_t());
    if (t == "float" || t == "float32") return as(float());
    return as(double());
  }
};

// OBJ, read here rather than by OpenMesh: Debian's OpenMesh is built with
// assertions, and its OBJ reader aborts the process on a face line without
// a usable vertex (found by fuzzing). Only geometry matters: "v x y z" (extra
// columns such as w or colours ignored) and "f i i i ..." with i, i/t, i//n
// or i/t/n, 1-based or negative (relative to the vertices so far); every
// other statement (vn, vt, o, g, s, usemtl, mtllib, l, p, ...) is skipped.
PolygonSoup read_obj(std::istream& in, const std::string& path) {
  PolygonSoup soup;
  std::vector<Eigen::Vector3d> points;
  std::string line;
  long long line_no = 0;
  auto fail = [&](const std::string& what) {
    throw InputError("'" + path + "' line " + std::to_string(line_no) + ": " + what);
  };
  // Words split as `std::istream >> std::string` splits them (C locale
  // white space), without a stream per line (issue 19: the stream and its
  // strings were 5% of mapping a 50k pair from OBJ files).
  std::string w;  // the current word, NUL-terminated for strtod / strtoll
  size_t pos = 0;
  auto is_space = [](char c) { return c == ' ' || c == '\t' || c == '\n' || c == '\v' || c == '\f' || c == '\r'; };
  auto next_word = [&] {
    while (pos < line.size() && is_space(line[pos])) ++pos;
    const size_t begin = pos;
    while (pos < line.size() && !is_space(line[pos])) ++pos;
    w.assign(line, begin, pos - begin);
    return pos > begin;
  };
  while (std::getline(in, line)) {
    ++line_no;
    const auto hash = line.find('#');
    if (hash != std::string::npos) line.resize(hash);
    pos = 0;
    if (!next_word()) continue;
    if (w == "v") {
      double x[3];
      for (double& c : x) {
        char* end = nullptr;
        if (!next_word()) fail("a vertex needs 3 coordinates");
        c = std::strtod(w.c_str(), &end);
        if (end == w.c_str() || *end != '\0') fail("'" + w.substr(0, 40) + "' is not a number");
      }
      points.emplace_back(x[0], x[1], x[2]);  // NaN and Inf pass: intake names the vertex
    } else if (w == "f") {
      std::vector<int> poly;
      while (next_word()) {
        const size_t slash = w.find('/');
        const std::string first = w.substr(0, slash);
        errno = 0;
        char* end = nullptr;
        const long long i = std::strtoll(first.c_str(), &end, 10);
        if (end == first.c_str() || *end != '\0' || errno == ERANGE)
          fail("face vertex '" + w.substr(0, 40) + "' is not an index");
        const long long zero_based = i > 0 ? i - 1 : static_cast<long long>(points.size()) + i;
        if (i == 0 || zero_based < 0 || zero_based > std::numeric_limits<int>::max())
          fail("face vertex index " + first + " does not name a vertex (" + std::to_string(points.size()) +
               " vertices so far)");
        poly.push_back(static_cast<int>(zero_based));
      }
      soup.polygons.push_back(std::move(poly));
    }
  }
  soup.V.resize(static_cast<int>(points.size()), 3);
  for (size_t i = 0; i < points.size(); ++i) soup.V.row(static_cast<int>(i)) = points[i].transpose();
  return soup;
}

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
  if (ext != ".stl") {
    std::ifstream in(path, std::ios::binary);
    if (!in) throw InputError("'" + path + "' cannot be opened for reading");
    PolygonSoup soup = ext == ".off" ? OffReader(in, path).read()
                       : ext == ".ply" ? PlyReader(in, path).read()
                                       : read_obj(in, path);
    if (soup.polygons.empty()) throw InputError("'" + path + "' contains no faces");
    return soup;
  }
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
