// Reconstructs a surface from an oriented point cloud through a small RAII wrapper over the psr
// C API, and prints the mesh's size and isovalue.
//
//   reconstruct_cpp [cloud.ply [depth]]
//
// The wrapper (namespace psrpp) owns each handle in one object, turns every error status into
// an exception carrying the handle's message, and keeps C++ exceptions from crossing the C
// progress callback.
#include <psr.h>

#include <cstdint>
#include <cstdio>
#include <cstring>
#include <exception>
#include <fstream>
#include <functional>
#include <iostream>
#include <sstream>
#include <stdexcept>
#include <string>
#include <utility>
#include <vector>

#ifndef PSR_EXAMPLE_DATA
#define PSR_EXAMPLE_DATA "kitten_cgal.ply"
#endif

namespace psrpp {

class Error : public std::runtime_error {
public:
    Error(psr_status status, const std::string &message)
        : std::runtime_error(std::string(psr_status_string(static_cast<int>(status))) + ": " + message),
          status_(status) {}
    psr_status status() const noexcept { return status_; }

private:
    psr_status status_;
};

// A reconstructed mesh; move-only, freed on destruction. Independent of its Reconstructor.
class Mesh {
public:
    explicit Mesh(psr_mesh *mesh) noexcept : mesh_(mesh) {}
    Mesh(Mesh &&other) noexcept : mesh_(std::exchange(other.mesh_, nullptr)) {}
    Mesh &operator=(Mesh &&other) noexcept {
        std::swap(mesh_, other.mesh_);
        return *this;
    }
    Mesh(const Mesh &) = delete;
    Mesh &operator=(const Mesh &) = delete;
    ~Mesh() { psr_mesh_free(mesh_); }

    std::size_t vertex_count() const noexcept { return psr_mesh_vertex_count(mesh_); }
    std::size_t triangle_count() const noexcept { return psr_mesh_triangle_count(mesh_); }
    double isovalue() const noexcept { return psr_mesh_isovalue(mesh_); }
    // Borrowed: valid while this Mesh lives.
    const float *positions() const noexcept { return psr_mesh_positions(mesh_); }
    const std::uint32_t *triangles() const noexcept { return psr_mesh_triangles(mesh_); }
    // Owned copies.
    std::vector<float> copy_positions() const {
        std::vector<float> out(3 * vertex_count());
        check(psr_mesh_copy_positions(mesh_, out.data(), out.size()));
        return out;
    }
    std::vector<std::uint32_t> copy_triangles() const {
        std::vector<std::uint32_t> out(3 * triangle_count());
        check(psr_mesh_copy_triangles(mesh_, out.data(), out.size()));
        return out;
    }

private:
    static void check(psr_status status) {
        if (status != PSR_STATUS_OK) throw Error(status, "copying the mesh failed");
    }
    psr_mesh *mesh_;
};

// Parameters and points; move-only, freed on destruction.
class Reconstructor {
public:
    using Progress = std::function<bool(psr_stage, float)>;

    Reconstructor() {
        psr_reconstructor *r = nullptr;
        psr_status status = psr_reconstructor_new(&r);
        if (status != PSR_STATUS_OK) throw Error(status, "psr_reconstructor_new failed");
        r_ = r;
    }
    Reconstructor(Reconstructor &&other) noexcept
        : r_(std::exchange(other.r_, nullptr)), progress_(std::move(other.progress_)) {}
    Reconstructor(const Reconstructor &) = delete;
    Reconstructor &operator=(const Reconstructor &) = delete;
    Reconstructor &operator=(Reconstructor &&) = delete;
    ~Reconstructor() { psr_reconstructor_free(r_); }

    Reconstructor &depth(std::uint32_t d) { return check(psr_reconstructor_set_depth(r_, d)); }
    Reconstructor &threads(std::uint32_t n) { return check(psr_reconstructor_set_threads(r_, n)); }
    Reconstructor &point_weight(float w) { return check(psr_reconstructor_set_point_weight(r_, w)); }
    std::uint32_t depth() const {
        std::uint32_t d = 0;
        check(psr_reconstructor_get_depth(r_, &d));
        return d;
    }

    // Points as interleaved or separate float arrays; stride 0 = packed x y z.
    Reconstructor &add_points(const float *positions, std::size_t position_stride, const float *normals,
                              std::size_t normal_stride, std::size_t count) {
        return check(psr_reconstructor_add_points(r_, positions, position_stride, normals, normal_stride, count));
    }
    std::size_t point_count() const {
        std::size_t n = 0;
        check(psr_reconstructor_point_count(r_, &n));
        return n;
    }

    // The callback may throw: the exception stops the solve and is rethrown from solve().
    Reconstructor &on_progress(Progress progress) {
        progress_ = std::move(progress);
        return check(psr_reconstructor_set_progress_callback(r_, progress_ ? &trampoline : nullptr, this));
    }

    Mesh solve() {
        pending_ = nullptr;
        psr_mesh *mesh = nullptr;
        psr_status status = psr_reconstructor_solve(r_, &mesh);
        if (pending_) std::rethrow_exception(std::exchange(pending_, nullptr));
        check(status);
        return Mesh(mesh);
    }

private:
    // C callbacks must not unwind: catch everything and cancel instead.
    static bool trampoline(void *user, psr_stage stage, float fraction) {
        auto *self = static_cast<Reconstructor *>(user);
        try {
            return self->progress_(stage, fraction);
        } catch (...) {
            self->pending_ = std::current_exception();
            return false;
        }
    }
    Reconstructor &check(psr_status status) {
        static_cast<const Reconstructor *>(this)->check(status);
        return *this;
    }
    void check(psr_status status) const {
        if (status != PSR_STATUS_OK) throw Error(status, psr_reconstructor_last_error(r_));
    }

    psr_reconstructor *r_ = nullptr;
    Progress progress_;
    std::exception_ptr pending_;
};

}  // namespace psrpp

// Reads float x y z nx ny nz vertices from a binary little-endian PLY, interleaved.
static std::vector<float> read_ply(const std::string &path) {
    std::ifstream in(path, std::ios::binary);
    if (!in) throw std::runtime_error("cannot open " + path);
    std::string line;
    std::getline(in, line);
    if (line.rfind("ply", 0) != 0) throw std::runtime_error(path + " is not a PLY file");
    std::size_t count = 0;
    bool binary_le = false, in_vertex = false;
    std::vector<std::string> properties;
    while (std::getline(in, line) && line.rfind("end_header", 0) != 0) {
        std::istringstream words(line);
        std::string keyword, a, b;
        words >> keyword >> a >> b;
        if (keyword == "format") binary_le = a == "binary_little_endian";
        if (keyword == "element") {
            in_vertex = a == "vertex";
            if (in_vertex) count = std::stoul(b);
        }
        if (keyword == "property" && in_vertex) properties.push_back(a + " " + b);
    }
    const std::vector<std::string> expected = {"float x", "float y", "float z", "float nx", "float ny", "float nz"};
    if (!binary_le || properties != expected || count == 0)
        throw std::runtime_error(path + ": need binary_little_endian vertices with float x y z nx ny nz");
    std::uint16_t probe = 1;
    unsigned char first = 0;
    std::memcpy(&first, &probe, 1);
    if (first != 1) throw std::runtime_error("this example reader only runs on little-endian machines");
    std::vector<float> data(6 * count);
    if (!in.read(reinterpret_cast<char *>(data.data()), static_cast<std::streamsize>(data.size() * sizeof(float))))
        throw std::runtime_error(path + ": truncated vertex data");
    return data;
}

int main(int argc, char **argv) {
    try {
        const std::string path = argc > 1 ? argv[1] : PSR_EXAMPLE_DATA;
        const std::uint32_t depth = argc > 2 ? static_cast<std::uint32_t>(std::stoul(argv[2])) : 7;
        const std::vector<float> cloud = read_ply(path);
        const std::size_t count = cloud.size() / 6;
        std::cout << "psr " << psr_version() << ": " << count << " points from " << path << ", depth " << depth
                  << "\n";

        psrpp::Reconstructor reconstructor;
        int last_stage = -1;
        reconstructor.depth(depth).on_progress([&](psr_stage stage, float) {
            if (static_cast<int>(stage) != last_stage) {
                std::cerr << "  stage: " << psr_stage_string(static_cast<int>(stage)) << "\n";
                last_stage = static_cast<int>(stage);
            }
            return true;
        });
        reconstructor.add_points(cloud.data(), 6 * sizeof(float), cloud.data() + 3, 6 * sizeof(float), count);

        // Errors come back as exceptions with the library's message.
        try {
            reconstructor.depth(99);
        } catch (const psrpp::Error &e) {
            std::cout << "rejected as expected: " << e.what() << "\n";
        }

        psrpp::Mesh mesh = reconstructor.solve();
        const std::vector<float> positions = mesh.copy_positions();
        std::cout << "vertices: " << mesh.vertex_count() << "\n"
                  << "triangles: " << mesh.triangle_count() << "\n"
                  << "isovalue: " << mesh.isovalue() << "\n";
        if (positions.size() != 3 * mesh.vertex_count() || mesh.triangle_count() == 0 ||
            reconstructor.point_count() != count)
            return 1;
        return 0;
    } catch (const std::exception &e) {
        std::cerr << "error: " << e.what() << "\n";
        return 1;
    }
}
