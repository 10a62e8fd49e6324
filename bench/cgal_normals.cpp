// CGAL's normal estimation and orientation, timed the way bench/normals.py times psr's and
// Open3D's: CGAL::jet_estimate_normals (k nearest neighbours, jet fitting) then
// CGAL::mst_orient_normals (minimum spanning tree propagation over the k-neighbour graph, seeded
// at the highest point, whose normal is turned to +z) on the file's positions, then the share of
// the normals that agree in sign with the file's own.
//
// CGAL's neighbour queries ask for k + 1 points and count the query point itself, so its k means
// the same as psr's (Open3D needs k + 1 for that). mst_orient_normals moves the points it could
// not orient to the end of the range; they are counted and left out of the agreement, which is
// then over the oriented points only (the share of all points is printed too, unoriented ones
// counted as disagreeing).
//
// jet_estimate_normals runs on TBB threads when built with TBB (-DCGAL_LINKED_WITH_TBB -ltbb),
// sequentially otherwise; mst_orient_normals is always sequential. Build (see bench/README.md):
//
//   g++ -O3 -DNDEBUG -std=c++17 -DCGAL_LINKED_WITH_TBB bench/cgal_normals.cpp \
//       -o target/cgal_normals -ltbb -lgmp -lmpfr
//   target/cgal_normals IN.ply [--neighbors 20] [--threads 0]
//
// The reader takes PLY files (ascii or binary little-endian) whose first element is `vertex`
// with scalar properties x, y, z and optionally nx, ny, nz.

#include <CGAL/Exact_predicates_inexact_constructions_kernel.h>
#include <CGAL/jet_estimate_normals.h>
#include <CGAL/mst_orient_normals.h>
#include <CGAL/property_map.h>

#ifdef CGAL_LINKED_WITH_TBB
#include <tbb/global_control.h>
#endif

#include <chrono>
#include <cstdint>
#include <cstdio>
#include <cstring>
#include <fstream>
#include <iostream>
#include <memory>
#include <sstream>
#include <stdexcept>
#include <string>
#include <tuple>
#include <vector>

using Kernel = CGAL::Exact_predicates_inexact_constructions_kernel;
using Point = Kernel::Point_3;
using Vector = Kernel::Vector_3;
// Position, estimated normal, index into the file's normals (the orientation reorders points).
using Sample = std::tuple<Point, Vector, std::size_t>;

namespace {

struct Cloud {
  std::vector<double> positions;  // x y z per point
  std::vector<double> normals;    // nx ny nz per point, empty when the file has none
};

std::size_t type_size(const std::string& type) {
  if (type == "char" || type == "uchar" || type == "int8" || type == "uint8") return 1;
  if (type == "short" || type == "ushort" || type == "int16" || type == "uint16") return 2;
  if (type == "int" || type == "uint" || type == "int32" || type == "uint32" || type == "float" ||
      type == "float32")
    return 4;
  if (type == "double" || type == "float64") return 8;
  throw std::runtime_error("unknown PLY property type " + type);
}

double decode(const std::string& type, const unsigned char* bytes) {
  // Little-endian host assumed (x86-64, aarch64), as for the files bench/ reads.
  auto as = [bytes](auto value) {
    std::memcpy(&value, bytes, sizeof value);
    return static_cast<double>(value);
  };
  if (type == "char" || type == "int8") return as(std::int8_t{});
  if (type == "uchar" || type == "uint8") return as(std::uint8_t{});
  if (type == "short" || type == "int16") return as(std::int16_t{});
  if (type == "ushort" || type == "uint16") return as(std::uint16_t{});
  if (type == "int" || type == "int32") return as(std::int32_t{});
  if (type == "uint" || type == "uint32") return as(std::uint32_t{});
  if (type == "float" || type == "float32") return as(float{});
  return as(double{});
}

Cloud read_ply(const std::string& path) {
  std::ifstream in(path, std::ios::binary);
  if (!in) throw std::runtime_error("cannot open " + path);
  std::string line;
  std::getline(in, line);
  if (line.rfind("ply", 0) != 0) throw std::runtime_error(path + " is not a PLY file");
  std::string format;
  std::size_t count = 0;
  bool in_vertex = false, seen_element = false;
  std::vector<std::string> types;
  std::vector<std::string> names;
  while (std::getline(in, line)) {
    if (!line.empty() && line.back() == '\r') line.pop_back();
    std::istringstream words(line);
    std::string keyword;
    words >> keyword;
    if (keyword == "format") {
      words >> format;
    } else if (keyword == "element") {
      std::string name;
      words >> name;
      if (!seen_element) {
        if (name != "vertex") throw std::runtime_error("the first element is not vertex");
        words >> count;
        in_vertex = true;
      } else {
        in_vertex = false;
      }
      seen_element = true;
    } else if (keyword == "property" && in_vertex) {
      std::string type, name;
      words >> type;
      if (type == "list") throw std::runtime_error("list properties on vertices are not read");
      words >> name;
      types.push_back(type);
      names.push_back(name);
    } else if (keyword == "end_header") {
      break;
    }
  }
  if (format != "ascii" && format != "binary_little_endian")
    throw std::runtime_error("unsupported PLY format " + format);
  const char* wanted[6] = {"x", "y", "z", "nx", "ny", "nz"};
  int column[6] = {-1, -1, -1, -1, -1, -1};
  for (int w = 0; w < 6; ++w)
    for (std::size_t p = 0; p < names.size(); ++p)
      if (names[p] == wanted[w]) column[w] = static_cast<int>(p);
  if (column[0] < 0 || column[1] < 0 || column[2] < 0)
    throw std::runtime_error("the vertices have no x, y, z");
  const bool with_normals = column[3] >= 0 && column[4] >= 0 && column[5] >= 0;

  Cloud cloud;
  cloud.positions.resize(3 * count);
  if (with_normals) cloud.normals.resize(3 * count);
  std::vector<double> values(names.size());
  if (format == "ascii") {
    for (std::size_t i = 0; i < count; ++i) {
      for (double& value : values)
        if (!(in >> value)) throw std::runtime_error("the file ends early");
      for (int c = 0; c < 3; ++c) cloud.positions[3 * i + c] = values[column[c]];
      if (with_normals)
        for (int c = 0; c < 3; ++c) cloud.normals[3 * i + c] = values[column[3 + c]];
    }
  } else {
    std::vector<std::size_t> offset(names.size());
    std::size_t stride = 0;
    for (std::size_t p = 0; p < names.size(); ++p) {
      offset[p] = stride;
      stride += type_size(types[p]);
    }
    std::vector<unsigned char> bytes(stride * count);
    if (!in.read(reinterpret_cast<char*>(bytes.data()), static_cast<std::streamsize>(bytes.size())))
      throw std::runtime_error("the file ends early");
    for (std::size_t i = 0; i < count; ++i) {
      const unsigned char* record = bytes.data() + i * stride;
      for (int c = 0; c < 3; ++c)
        cloud.positions[3 * i + c] = decode(types[column[c]], record + offset[column[c]]);
      if (with_normals)
        for (int c = 0; c < 3; ++c)
          cloud.normals[3 * i + c] =
              decode(types[column[3 + c]], record + offset[column[3 + c]]);
    }
  }
  return cloud;
}

}  // namespace

int main(int argc, char** argv) {
  std::string input;
  unsigned int k = 20;
  int threads = 0;
  for (int a = 1; a < argc; ++a) {
    std::string arg = argv[a];
    if (arg == "--neighbors" && a + 1 < argc) {
      k = static_cast<unsigned int>(std::stoul(argv[++a]));
    } else if (arg == "--threads" && a + 1 < argc) {
      threads = std::stoi(argv[++a]);
    } else if (input.empty() && arg.rfind("--", 0) != 0) {
      input = arg;
    } else {
      std::cerr << "usage: cgal_normals IN.ply [--neighbors 20] [--threads 0]\n";
      return 2;
    }
  }
  if (input.empty()) {
    std::cerr << "usage: cgal_normals IN.ply [--neighbors 20] [--threads 0]\n";
    return 2;
  }

#ifdef CGAL_LINKED_WITH_TBB
  using Concurrency = CGAL::Parallel_tag;
  const char* mode = "TBB";
  std::unique_ptr<tbb::global_control> limit;
  if (threads > 0)
    limit = std::make_unique<tbb::global_control>(tbb::global_control::max_allowed_parallelism,
                                                  static_cast<std::size_t>(threads));
#else
  using Concurrency = CGAL::Sequential_tag;
  const char* mode = "sequential (no TBB)";
#endif

  Cloud cloud;
  try {
    cloud = read_ply(input);
  } catch (const std::exception& error) {
    std::cerr << "cgal_normals: " << error.what() << "\n";
    return 1;
  }
  const std::size_t n = cloud.positions.size() / 3;
  std::vector<Sample> samples;
  samples.reserve(n);
  for (std::size_t i = 0; i < n; ++i)
    samples.emplace_back(
        Point(cloud.positions[3 * i], cloud.positions[3 * i + 1], cloud.positions[3 * i + 2]),
        Vector(0, 0, 0), i);

  const auto params = CGAL::parameters::point_map(CGAL::Nth_of_tuple_property_map<0, Sample>())
                          .normal_map(CGAL::Nth_of_tuple_property_map<1, Sample>());
  using Clock = std::chrono::steady_clock;
  const auto started = Clock::now();
  CGAL::jet_estimate_normals<Concurrency>(samples, k, params);
  const auto estimated = Clock::now();
  const auto first_unoriented = CGAL::mst_orient_normals(samples, k, params);
  const auto oriented = Clock::now();

  const std::size_t kept = static_cast<std::size_t>(first_unoriented - samples.begin());
  const std::size_t unoriented = n - kept;
  std::string agreement;
  if (!cloud.normals.empty() && kept > 0) {
    std::size_t agree = 0;
    for (auto it = samples.begin(); it != first_unoriented; ++it) {
      const Vector& normal = std::get<1>(*it);
      const double* given = &cloud.normals[3 * std::get<2>(*it)];
      if (normal.x() * given[0] + normal.y() * given[1] + normal.z() * given[2] > 0.0) ++agree;
    }
    char text[256];
    std::snprintf(text, sizeof text,
                  "; %.3f %% agree in sign with the file's normals (over the %zu oriented "
                  "points; %.3f %% of all %zu points)",
                  100.0 * static_cast<double>(agree) / static_cast<double>(kept), kept,
                  100.0 * static_cast<double>(agree) / static_cast<double>(n), n);
    agreement = text;
  }
  auto seconds = [](Clock::time_point from, Clock::time_point to) {
    return std::chrono::duration<double>(to - from).count();
  };
  std::printf(
      "cgal_normals: %zu points, k = %u, %s, estimated in %.2f s and oriented in %.2f s, "
      "total %.2f s; %zu points left unoriented (removed)%s\n",
      n, k, mode, seconds(started, estimated), seconds(estimated, oriented),
      seconds(started, oriented), unoriented, agreement.c_str());
  return 0;
}
