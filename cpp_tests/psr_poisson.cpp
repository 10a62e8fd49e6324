// psr through its C API, as a C++ user of the installed package calls it.
#include "reconstructors.hpp"

#include <psr.h>

#include <chrono>
#include <memory>
#include <sstream>
#include <stdexcept>
#include <vector>

namespace recon {
namespace {

struct ReconstructorDeleter {
    void operator()(psr_reconstructor *r) const { psr_reconstructor_free(r); }
};
struct MeshDeleter {
    void operator()(psr_mesh *m) const { psr_mesh_free(m); }
};

void check(psr_status s, const psr_reconstructor *r, const char *what) {
    if (s != PSR_STATUS_OK)
        throw std::runtime_error(std::string(what) + ": " + psr_status_string(s) + ": " +
                                 psr_reconstructor_last_error(r));
}

} // namespace

Result run_psr(const inputs::Cloud &cloud, const OctreeParams &p) {
    psr_reconstructor *raw = nullptr;
    if (psr_reconstructor_new(&raw) != PSR_STATUS_OK) throw std::runtime_error("psr_reconstructor_new failed");
    std::unique_ptr<psr_reconstructor, ReconstructorDeleter> r(raw);

    // Every parameter set, even where it equals psr's default, so the comparison does not move
    // when a default does. The octree ones are shared with PCL (see OctreeParams); the solver
    // ones are psr's defaults: at most 60 conjugate-gradient iterations per depth, relative
    // residual 1e-2 per depth (PCL's solver accuracy is 1e-3, over its own Gauss-Seidel
    // schedule). Measured on the sphere and torus inputs: 1e-3 and 1e-5 give the same distances
    // to the truth within 1%, so the tolerance does not limit psr's accuracy here.
    check(psr_reconstructor_set_depth(r.get(), p.depth), r.get(), "set_depth");
    check(psr_reconstructor_set_full_depth(r.get(), p.full_depth), r.get(), "set_full_depth");
    check(psr_reconstructor_set_kernel_depth(r.get(), static_cast<int32_t>(p.depth) - 2), r.get(),
          "set_kernel_depth"); // depth - 2, as PoissonRecon and PCL (which hard-codes it)
    check(psr_reconstructor_set_samples_per_node(r.get(), p.samples_per_node), r.get(), "set_samples_per_node");
    check(psr_reconstructor_set_scale(r.get(), p.scale), r.get(), "set_scale");
    check(psr_reconstructor_set_point_weight(r.get(), p.point_weight), r.get(), "set_point_weight");
    check(psr_reconstructor_set_threads(r.get(), p.threads), r.get(), "set_threads");
    check(psr_reconstructor_set_max_solver_iterations(r.get(), 60), r.get(), "set_max_solver_iterations");
    check(psr_reconstructor_set_solver_tolerance(r.get(), 1e-2), r.get(), "set_solver_tolerance");
    // Fitted vertices (psr's default): found on the isosurface, then moved along the normal by
    // the mean sag of their chords so that the flat triangles straddle the curved surface. PCL
    // and CGAL have no such step; PCL's vertices come out about 1e-4 outside its isosurface on
    // the torus anyway (its isovalue is an average over node centres, not over the samples).
    check(psr_reconstructor_set_vertex_placement(r.get(), PSR_VERTEX_PLACEMENT_FITTED), r.get(),
          "set_vertex_placement");

    std::vector<float> xyz, nxyz;
    xyz.reserve(3 * cloud.size());
    nxyz.reserve(3 * cloud.size());
    for (std::size_t i = 0; i < cloud.size(); ++i)
        for (int k = 0; k < 3; ++k) {
            xyz.push_back(static_cast<float>(cloud.positions[i][k]));
            nxyz.push_back(static_cast<float>(cloud.normals[i][k]));
        }

    Result out;
    const auto t0 = std::chrono::steady_clock::now();
    check(psr_reconstructor_add_points(r.get(), xyz.data(), 0, nxyz.data(), 0, cloud.size()), r.get(), "add_points");
    psr_mesh *mraw = nullptr;
    check(psr_reconstructor_solve(r.get(), &mraw), r.get(), "solve");
    std::unique_ptr<psr_mesh, MeshDeleter> m(mraw);
    out.seconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();

    const std::size_t nv = psr_mesh_vertex_count(m.get()), nt = psr_mesh_triangle_count(m.get());
    const float *pos = psr_mesh_positions(m.get());
    const uint32_t *tri = psr_mesh_triangles(m.get());
    out.mesh.vertices.resize(nv);
    for (std::size_t i = 0; i < nv; ++i) out.mesh.vertices[i] = {pos[3 * i], pos[3 * i + 1], pos[3 * i + 2]};
    out.mesh.triangles.resize(nt);
    for (std::size_t i = 0; i < nt; ++i) out.mesh.triangles[i] = {tri[3 * i], tri[3 * i + 1], tri[3 * i + 2]};

    std::ostringstream s;
    s << "psr " << psr_version() << ": depth " << p.depth << ", full_depth " << p.full_depth << ", kernel_depth "
      << p.depth - 2 << ", samples_per_node " << p.samples_per_node << ", scale " << p.scale << ", point_weight "
      << p.point_weight << ", threads " << p.threads << ", max_solver_iterations 60, solver_tolerance 1e-2, vertex_placement fitted";
    out.settings = s.str();
    return out;
}

} // namespace recon
