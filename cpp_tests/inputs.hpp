// The inputs of the comparison tests: oriented point sets sampled from analytic shapes with fixed
// seeds (exact surface, area and volume known), and the real scans of the shared data directory
// read from PLY.
#pragma once

#include "mesh_metrics.hpp"

#include <cmath>
#include <cstdint>
#include <cstdlib>
#include <cstring>
#include <fstream>
#include <functional>
#include <sstream>
#include <stdexcept>
#include <string>
#include <vector>

namespace inputs {

using metrics::Vec3;

constexpr double kPi = 3.14159265358979323846;

// Oriented points: positions and unit normals, one Vec3 each.
struct Cloud {
    std::vector<Vec3> positions;
    std::vector<Vec3> normals;
    std::size_t size() const { return positions.size(); }
};

// Keeps every k-th point (0, k, 2k, ...): deterministic, and a quarter of each scan of a merged
// file for k = 4, since a scan's points are stored together and in scan-line order.
inline Cloud every_kth(const Cloud &in, std::size_t k) {
    Cloud out;
    for (std::size_t i = 0; i < in.size(); i += k) {
        out.positions.push_back(in.positions[i]);
        out.normals.push_back(in.normals[i]);
    }
    return out;
}

// ---------------------------------------------------------------------------------------------
// Analytic shapes

// A closed surface with its exact distance function, area and enclosed volume.
struct Shape {
    std::string name;
    Cloud cloud;                                  // the input points, exact normals
    std::function<double(const Vec3 &)> distance; // unsigned distance to the true surface
    std::function<std::vector<Vec3>(std::size_t, std::uint64_t)> sample; // area-uniform samples
    double area = 0.0;
    double volume = 0.0;
};

// A sphere of radius r around c. Points: normalised Gaussian vectors (uniform on the sphere).
inline Shape sphere(const Vec3 &c, double r, std::size_t n, std::uint64_t seed) {
    Shape s;
    s.name = "sphere";
    auto sample_dirs = [](std::size_t count, std::uint64_t sd) {
        metrics::Rng rng(sd);
        std::vector<Vec3> dirs;
        dirs.reserve(count);
        while (dirs.size() < count) {
            const Vec3 g{rng.normal(), rng.normal(), rng.normal()};
            const double len = metrics::norm(g);
            if (len > 1e-9) dirs.push_back((1.0 / len) * g);
        }
        return dirs;
    };
    for (const Vec3 &d : sample_dirs(n, seed)) {
        s.cloud.positions.push_back(c + r * d);
        s.cloud.normals.push_back(d);
    }
    s.distance = [c, r](const Vec3 &p) { return std::abs(metrics::norm(p - c) - r); };
    s.sample = [c, r, sample_dirs](std::size_t count, std::uint64_t sd) {
        std::vector<Vec3> out;
        for (const Vec3 &d : sample_dirs(count, sd)) out.push_back(c + r * d);
        return out;
    };
    s.area = 4.0 * kPi * r * r;
    s.volume = 4.0 / 3.0 * kPi * r * r * r;
    return s;
}

// A ring torus around the z axis through c: major radius R, minor radius r. Area-uniform points
// by rejection: the area element is proportional to R + r cos(v).
inline Shape torus(const Vec3 &c, double R, double r, std::size_t n, std::uint64_t seed) {
    Shape s;
    s.name = "torus";
    auto sample_uv = [R, r](std::size_t count, std::uint64_t sd) {
        metrics::Rng rng(sd);
        std::vector<std::pair<double, double>> uv;
        uv.reserve(count);
        while (uv.size() < count) {
            const double u = 2.0 * kPi * rng.uniform(), v = 2.0 * kPi * rng.uniform();
            if (rng.uniform() * (R + r) <= R + r * std::cos(v)) uv.emplace_back(u, v);
        }
        return uv;
    };
    for (const auto &[u, v] : sample_uv(n, seed)) {
        const Vec3 nrm{std::cos(v) * std::cos(u), std::cos(v) * std::sin(u), std::sin(v)};
        const Vec3 ring{R * std::cos(u), R * std::sin(u), 0.0};
        s.cloud.positions.push_back(c + ring + r * nrm);
        s.cloud.normals.push_back(nrm);
    }
    s.distance = [c, R, r](const Vec3 &p) {
        const Vec3 q = p - c;
        const double rho = std::hypot(q[0], q[1]) - R;
        return std::abs(std::hypot(rho, q[2]) - r);
    };
    s.sample = [c, R, r, sample_uv](std::size_t count, std::uint64_t sd) {
        std::vector<Vec3> out;
        for (const auto &[u, v] : sample_uv(count, sd))
            out.push_back(c + Vec3{(R + r * std::cos(v)) * std::cos(u), (R + r * std::cos(v)) * std::sin(u),
                                   r * std::sin(v)});
        return out;
    };
    s.area = 4.0 * kPi * kPi * R * r;
    s.volume = 2.0 * kPi * kPi * R * r * r;
    return s;
}

// ---------------------------------------------------------------------------------------------
// PLY point sets: ASCII or binary little-endian, a first element `vertex` with scalar properties
// including x y z nx ny nz (float or double); other properties (colour, ...) are skipped.

inline Cloud read_ply(const std::string &path) {
    std::ifstream in(path, std::ios::binary);
    if (!in) throw std::runtime_error("cannot open " + path);
    std::string line;
    std::getline(in, line);
    if (line.rfind("ply", 0) != 0) throw std::runtime_error(path + ": not a PLY file");
    enum class Format { Ascii, BinaryLE } format = Format::Ascii;
    struct Property {
        std::string name, type;
    };
    std::vector<Property> props;
    std::size_t count = 0;
    bool in_vertex = false, seen_element = false;
    while (std::getline(in, line)) {
        if (!line.empty() && line.back() == '\r') line.pop_back();
        std::istringstream ls(line);
        std::string word;
        ls >> word;
        if (word == "format") {
            std::string f;
            ls >> f;
            if (f == "ascii") format = Format::Ascii;
            else if (f == "binary_little_endian") format = Format::BinaryLE;
            else throw std::runtime_error(path + ": unsupported PLY format " + f);
        } else if (word == "element") {
            std::string name;
            ls >> name;
            if (!seen_element && name != "vertex") throw std::runtime_error(path + ": first element is not vertex");
            in_vertex = name == "vertex";
            if (in_vertex) ls >> count;
            seen_element = true;
        } else if (word == "property" && in_vertex) {
            Property p;
            ls >> p.type;
            if (p.type == "list") throw std::runtime_error(path + ": list property in vertex");
            ls >> p.name;
            props.push_back(p);
        } else if (word == "end_header") {
            break;
        }
    }
    auto type_size = [&](const std::string &t) -> std::size_t {
        if (t == "char" || t == "uchar" || t == "int8" || t == "uint8") return 1;
        if (t == "short" || t == "ushort" || t == "int16" || t == "uint16") return 2;
        if (t == "int" || t == "uint" || t == "float" || t == "int32" || t == "uint32" || t == "float32") return 4;
        if (t == "double" || t == "float64") return 8;
        throw std::runtime_error(path + ": unknown PLY type " + t);
    };
    const char *wanted[6] = {"x", "y", "z", "nx", "ny", "nz"};
    int slot[6];
    for (int k = 0; k < 6; ++k) {
        slot[k] = -1;
        for (std::size_t i = 0; i < props.size(); ++i)
            if (props[i].name == wanted[k]) slot[k] = static_cast<int>(i);
        if (slot[k] < 0) throw std::runtime_error(path + ": no vertex property " + wanted[k]);
        const std::string &t = props[slot[k]].type;
        if (t != "float" && t != "float32" && t != "double" && t != "float64")
            throw std::runtime_error(path + ": property " + wanted[k] + " is not float or double");
    }
    Cloud cloud;
    cloud.positions.resize(count);
    cloud.normals.resize(count);
    std::vector<double> values(props.size());
    std::vector<std::size_t> offsets(props.size());
    std::size_t stride = 0;
    for (std::size_t i = 0; i < props.size(); ++i) {
        offsets[i] = stride;
        stride += type_size(props[i].type);
    }
    std::vector<char> record(stride);
    for (std::size_t v = 0; v < count; ++v) {
        if (format == Format::Ascii) {
            for (double &x : values)
                if (!(in >> x)) throw std::runtime_error(path + ": truncated at vertex " + std::to_string(v));
        } else {
            if (!in.read(record.data(), static_cast<std::streamsize>(stride)))
                throw std::runtime_error(path + ": truncated at vertex " + std::to_string(v));
            for (int k = 0; k < 6; ++k) { // little-endian host assumed (x86-64, aarch64)
                const std::size_t o = offsets[slot[k]];
                if (type_size(props[slot[k]].type) == 4) {
                    float f;
                    std::memcpy(&f, record.data() + o, 4);
                    values[slot[k]] = f;
                } else {
                    std::memcpy(&values[slot[k]], record.data() + o, 8);
                }
            }
        }
        cloud.positions[v] = {values[slot[0]], values[slot[1]], values[slot[2]]};
        cloud.normals[v] = {values[slot[3]], values[slot[4]], values[slot[5]]};
    }
    return cloud;
}

// ---------------------------------------------------------------------------------------------
// The shared data directory: $PSR_DATA_DIR, else ../shared/data relative to the repository.

inline std::string data_dir() {
    if (const char *d = std::getenv("PSR_DATA_DIR"); d && *d) return d;
#ifdef PSR_REPO_DIR
    return std::string(PSR_REPO_DIR) + "/../shared/data";
#else
    return "../shared/data";
#endif
}

// True when running in CI (the CI variable set and not "false"/"0"): there a missing data file
// fails the test instead of skipping it.
inline bool in_ci() {
    const char *ci = std::getenv("CI");
    return ci && *ci && std::strcmp(ci, "false") != 0 && std::strcmp(ci, "0") != 0;
}

} // namespace inputs
