// psr against CGAL's and PCL's Poisson reconstructions, by measurement (never by equality):
// the same oriented points go to the three, every parameter is set on each side
// (reconstructors.hpp and the three *_poisson.cpp files say which and why), and the meshes are
// measured by the same code (mesh_metrics.hpp). Each test prints a table of time, size,
// topology, area, volume and distances, writes it to $PSR_COMPARISONS_DIR when that is set
// (.ci/cpp_tests.sh gathers them into docs/comparisons.md), then checks psr against the others
// and, on the analytic shapes, against the exact surface.
//
// Inputs: a sphere and a torus sampled with fixed seeds (exact surface, area and volume known),
// and three real point sets from the shared data directory ($PSR_DATA_DIR, else ../shared/data
// next to the repository). A missing data file skips its test with a message, or fails it when
// CI is set.
#include "inputs.hpp"
#include "mesh_metrics.hpp"
#include "reconstructors.hpp"
#include "report.hpp"

#include <gtest/gtest.h>

#include <algorithm>
#include <cstdio>
#include <fstream>
#include <memory>
#include <optional>
#include <string>
#include <vector>

namespace {

using metrics::Vec3;
using report::format;
using report::permille;

// Samples per surface for the distances: 100,000 area-uniform samples put the standard error
// of a mean distance well under 1% of it, and the 95th percentile within a few tenths of a
// percent, far below the tolerances below; every seed is fixed, so the numbers are repeatable.
constexpr std::size_t kSamples = 100000;
constexpr std::uint64_t kSampleSeed = 20240601;
constexpr std::uint64_t kTruthSeed = 7;
// On the analytic shapes psr must be within this factor of the better of CGAL and PCL in
// distance to the exact surface (issue 4; see check_truth_distance).
constexpr double kTarget = 1.1;

// What one input is and how it is reconstructed.
struct Input {
    int order = 0;                     // position in docs/comparisons.md
    std::string name;                  // file name of its section
    std::string title;                 // heading
    std::string note;                  // how the points were made or chosen
    inputs::Cloud cloud;
    std::optional<inputs::Shape> shape; // the exact surface, for the analytic inputs
    recon::OctreeParams octree;
    recon::CgalParams cgal;
};

// One reconstruction and its measurements.
struct Measured {
    std::string method;
    recon::Result result;
    metrics::Topology topo;
    double area = 0.0, volume = 0.0;
    std::unique_ptr<metrics::Measured> surface; // samples + BVH
    metrics::Symmetric to_truth;                // analytic inputs only
    metrics::OneSided input_to_mesh;            // from every input point to the mesh
};

struct Comparison {
    double diagonal = 0.0; // of the input points' bounding box: the unit of every distance
    double cell = 0.0;     // psr's and PCL's finest octree cell, as a fraction of the diagonal
    std::vector<Measured> methods; // psr, CGAL, PCL
    metrics::Symmetric psr_cgal, psr_pcl, cgal_pcl;
    std::string markdown;
    const Measured &psr() const { return methods[0]; }
    const Measured &cgal() const { return methods[1]; }
    const Measured &pcl() const { return methods[2]; }
};

Measured measure(std::string method, recon::Result result, const Input &in, double diagonal) {
    Measured m;
    m.method = std::move(method);
    m.result = std::move(result);
    m.topo = metrics::topology(m.result.mesh);
    m.area = metrics::area(m.result.mesh);
    m.volume = metrics::signed_volume(m.result.mesh);
    if (m.result.mesh.triangles.empty()) return m;
    m.surface = std::make_unique<metrics::Measured>(m.result.mesh, kSamples, kSampleSeed);
    if (in.shape) {
        const std::vector<Vec3> truth = in.shape->sample(kSamples, kTruthSeed);
        m.to_truth = {metrics::one_sided(m.surface->samples, in.shape->distance, diagonal),
                      metrics::one_sided(truth, m.surface->distance, diagonal)};
    }
    m.input_to_mesh = metrics::one_sided(in.cloud.positions, m.surface->distance, diagonal);
    return m;
}

std::string yes_no(bool b) { return b ? "yes" : "no"; }

std::string render(const Input &in, const Comparison &c) {
    std::string md = format("### %s\n\n", in.title.c_str());
    md += in.note + "\n\n";
    for (const Measured &m : c.methods) md += "- " + m.result.settings + "\n";
    md += format("\nDistances are in thousandths of the input's bounding-box diagonal (%.6g); the octree cell at "
                 "depth %u is %.3f of them, and bounds CGAL's facet radius. ",
                 c.diagonal, in.octree.depth, 1e3 * c.cell);
    md += in.shape ? "*truth*: symmetric distances to the exact surface (Chamfer = sum, and average, of the two "
                     "one-sided mean distances; H95 = the larger one-sided 95th percentile). "
                   : "";
    md += "*input→mesh*: from every input point to the mesh (mean, 95th percentile). Volume is signed "
          "(positive = outward orientation). Times are wall-clock seconds on one thread.\n\n";

    std::vector<std::string> header = {"method", "time s", "vertices", "triangles", "closed", "bnd edges",
                                       "nm edges", "nm verts", "misoriented", "comps", "χ", "area", "volume"};
    if (in.shape) {
        for (const char *h : {"area err %", "vol err %", "truth Chamfer sum", "truth Chamfer avg", "truth H95"})
            header.push_back(h);
    }
    header.push_back("input→mesh mean");
    header.push_back("input→mesh p95");
    report::Table t(header);
    for (const Measured &m : c.methods) {
        std::vector<std::string> row = {m.method,
                                        format("%.2f", m.result.seconds),
                                        format("%zu", m.result.mesh.vertices.size()),
                                        format("%zu", m.result.mesh.triangles.size()),
                                        yes_no(m.topo.closed()),
                                        format("%zu", m.topo.boundary_edges),
                                        format("%zu", m.topo.nonmanifold_edges),
                                        format("%zu", m.topo.nonmanifold_vertices),
                                        format("%zu", m.topo.misoriented_edges),
                                        format("%zu", m.topo.components),
                                        format("%lld", m.topo.euler),
                                        format("%.6g", m.area),
                                        format("%.6g", m.volume)};
        if (in.shape) {
            row.push_back(format("%+.2f", 100.0 * (m.area / in.shape->area - 1.0)));
            row.push_back(format("%+.2f", 100.0 * (std::abs(m.volume) / in.shape->volume - 1.0)));
            row.push_back(permille(m.to_truth.chamfer_sum()));
            row.push_back(permille(m.to_truth.chamfer_avg()));
            row.push_back(permille(m.to_truth.hausdorff95()));
        }
        row.push_back(permille(m.input_to_mesh.mean));
        row.push_back(permille(m.input_to_mesh.p95));
        t.row(row);
    }
    if (in.shape) {
        std::vector<std::string> row = {"exact", "", "", "", "yes", "0", "0", "0", "0", "1",
                                        in.name == "torus" ? "0" : "2", format("%.6g", in.shape->area),
                                        format("%.6g", in.shape->volume)};
        row.resize(header.size());
        t.row(row);
    }
    md += t.str();

    report::Table pairs({"pair A ↔ B", "Chamfer sum", "Chamfer avg", "H95", "A→B mean", "B→A mean", "A→B p95",
                         "B→A p95"});
    auto pair_row = [&](const char *name, const metrics::Symmetric &s) {
        pairs.row({name, permille(s.chamfer_sum()), permille(s.chamfer_avg()), permille(s.hausdorff95()),
                   permille(s.a_to_b.mean), permille(s.b_to_a.mean), permille(s.a_to_b.p95),
                   permille(s.b_to_a.p95)});
    };
    if (in.shape) {
        const Measured &p = c.psr(), &g = c.cgal(), &l = c.pcl();
        md += format("\npsr's distance to the exact surface over CGAL's / PCL's: Chamfer %.2f× / %.2f×, H95 %.2f× / "
                     "%.2f× (target: at most %.1f× the better of the two).\n",
                     p.to_truth.chamfer_avg() / g.to_truth.chamfer_avg(),
                     p.to_truth.chamfer_avg() / l.to_truth.chamfer_avg(),
                     p.to_truth.hausdorff95() / g.to_truth.hausdorff95(),
                     p.to_truth.hausdorff95() / l.to_truth.hausdorff95(), kTarget);
        const double chamfer_gap = p.to_truth.chamfer_avg() /
                                   std::min(g.to_truth.chamfer_avg(), l.to_truth.chamfer_avg());
        const double h95_gap = p.to_truth.hausdorff95() /
                               std::min(g.to_truth.hausdorff95(), l.to_truth.hausdorff95());
        if (chamfer_gap > kTarget || h95_gap > kTarget)
            md += format("**Target missed:** psr is %.2f× (Chamfer) and %.2f× (H95) as far from the exact "
                         "surface as the better method, against a target of %.1f×.\n",
                         chamfer_gap, h95_gap, kTarget);
    }
    pair_row("psr ↔ CGAL", c.psr_cgal);
    pair_row("psr ↔ PCL", c.psr_pcl);
    pair_row("CGAL ↔ PCL", c.cgal_pcl);
    md += "\n" + pairs.str() + "\n";
    return md;
}

// The finest octree cell of psr and PCL at the input's depth: the reconstruction cube is the
// bounding box's largest side times the scale, split 2^depth times.
double octree_cell(const Input &in) {
    const metrics::Box box = metrics::bounding_box(in.cloud.positions);
    const Vec3 side = box.hi - box.lo;
    return in.octree.scale * std::max({side[0], side[1], side[2]}) / static_cast<double>(1u << in.octree.depth);
}

Comparison compare(Input in) {
    Comparison c;
    c.diagonal = metrics::bounding_box(in.cloud.positions).diagonal();
    // Comparable resolution: CGAL's facets no larger than psr's and PCL's cells. With CGAL's
    // own rule (30 average spacings) a sphere of 40,000 points gets 800 vertices and a distance
    // to the truth ten times psr's, which says nothing about either method.
    if (in.cgal.facet_radius <= 0.0) in.cgal.facet_radius = octree_cell(in);
    c.cell = octree_cell(in) / c.diagonal;
    std::printf("[ compare  ] %s: %zu points, running psr\n", in.name.c_str(), in.cloud.size());
    std::fflush(stdout);
    recon::Result psr = recon::run_psr(in.cloud, in.octree);
    std::printf("[ compare  ] %s: psr %.2f s, running CGAL\n", in.name.c_str(), psr.seconds);
    std::fflush(stdout);
    recon::Result cgal = recon::run_cgal(in.cloud, in.cgal);
    std::printf("[ compare  ] %s: CGAL %.2f s, running PCL\n", in.name.c_str(), cgal.seconds);
    std::fflush(stdout);
    recon::Result pcl = recon::run_pcl(in.cloud, in.octree);
    std::printf("[ compare  ] %s: PCL %.2f s, measuring\n", in.name.c_str(), pcl.seconds);
    std::fflush(stdout);
    c.methods.push_back(measure("psr", std::move(psr), in, c.diagonal));
    c.methods.push_back(measure("CGAL", std::move(cgal), in, c.diagonal));
    c.methods.push_back(measure("PCL", std::move(pcl), in, c.diagonal));
    for (const Measured &m : c.methods)
        if (!m.surface) throw std::runtime_error(m.method + " returned an empty mesh on " + in.name);
    c.psr_cgal = metrics::compare(*c.psr().surface, *c.cgal().surface, c.diagonal);
    c.psr_pcl = metrics::compare(*c.psr().surface, *c.pcl().surface, c.diagonal);
    c.cgal_pcl = metrics::compare(*c.cgal().surface, *c.pcl().surface, c.diagonal);
    c.markdown = render(in, c);
    std::printf("\n%s\n", c.markdown.c_str());
    std::fflush(stdout);
    if (const char *dir = std::getenv("PSR_COMPARISONS_DIR"); dir && *dir) {
        const std::string path = format("%s/%d_%s.md", dir, in.order, in.name.c_str());
        std::ofstream(path) << c.markdown;
    }
    return c;
}

// Reads a point set of the shared data directory. A missing file is a skip on a developer's
// machine and a failure in CI, where the data is part of the environment.
std::optional<inputs::Cloud> load_data(const std::string &file) {
    const std::string path = inputs::data_dir() + "/" + file;
    if (!std::ifstream(path)) return std::nullopt;
    return inputs::read_ply(path);
}

#define LOAD_OR_SKIP(var, file)                                                                              \
    std::optional<inputs::Cloud> var = load_data(file);                                                     \
    if (!var) {                                                                                              \
        const std::string msg = "missing " + inputs::data_dir() + "/" + (file) +                            \
                                " (set PSR_DATA_DIR to the shared data directory)";                         \
        if (inputs::in_ci()) FAIL() << msg << "; CI must have the data";                                    \
        GTEST_SKIP() << msg;                                                                                 \
    }

// ---------------------------------------------------------------------------------------------
// Checks. Every distance tolerance is a multiple of the finest octree cell at the input's depth
// (Comparison::cell, as a fraction of the diagonal like the distances): that is the resolution
// the three methods are run at, so a tolerance in cells means the same thing on every input.

// Agreement of psr with CGAL and with PCL. The three solve the same equation on different
// discretisations (psr and PCL on the octree, CGAL on a Delaunay refinement of the points), so
// their meshes differ by their discretisation errors and, on real scans, by how each smooths
// noise and fills sparsely sampled parts. Tolerances, in cells:
//   smooth, densely sampled, noise-free shapes: Chamfer average 0.05, H95 0.15. Measured at
//     most 0.022 and 0.062 (psr-CGAL on the sphere and torus); an isosurface shifted by a
//     twentieth of a cell, or a bump of a sixth of a cell over 5% of the surface, fails;
//   real scans: Chamfer average 0.25, H95 1. Measured at most 0.11 and 0.38 (psr-CGAL on the
//     kitten); a surface more than a cell away over 5% of it is a different surface.
struct Agreement {
    double chamfer_avg_cells;
    double h95_cells;
};
constexpr Agreement kSmoothAgreement{0.05, 0.15};
constexpr Agreement kScanAgreement{0.25, 1.0};

void check_agreement(const char *other, const metrics::Symmetric &d, double cell, const Agreement &tol) {
    EXPECT_LE(d.chamfer_avg(), tol.chamfer_avg_cells * cell)
        << "psr and " << other << " disagree: Chamfer average " << d.chamfer_avg() / cell << " cells, tolerance "
        << tol.chamfer_avg_cells;
    EXPECT_LE(d.hausdorff95(), tol.h95_cells * cell)
        << "psr and " << other << " disagree: 95% Hausdorff " << d.hausdorff95() / cell << " cells, tolerance "
        << tol.h95_cells;
}

// psr's mesh of a closed object: every edge in two triangles, every vertex one fan, consistent
// outward orientation (psr promises a closed 2-manifold by construction), in one piece with the
// object's Euler characteristic.
void check_manifold_only(const Measured &psr) {
    EXPECT_TRUE(psr.topo.closed_manifold())
        << "boundary edges " << psr.topo.boundary_edges << ", non-manifold edges " << psr.topo.nonmanifold_edges
        << ", non-manifold vertices " << psr.topo.nonmanifold_vertices << ", misoriented edges "
        << psr.topo.misoriented_edges << ", degenerate triangles " << psr.topo.degenerate;
    EXPECT_EQ(psr.topo.unreferenced, 0u);
    EXPECT_GT(psr.volume, 0.0) << "psr's triangles should face outwards";
}

void check_closed_manifold(const Measured &psr, long long euler) {
    check_manifold_only(psr);
    EXPECT_EQ(psr.topo.components, 1u);
    EXPECT_EQ(psr.topo.euler, euler);
}

// The analytic shapes.
//   Area and volume: within 0.5% of the exact values. Marching cubes on a smooth surface errs
//     by about (cell / radius of curvature)^2, here 3e-4 of the area (measured at most 0.06%);
//     an isosurface shifted by 0.15 cell changes the area by about 0.5% (sphere: 2 x shift / R).
//     The issue asks for "a few percent"; 0.5% is tighter and still leaves a 8x margin.
//   Distance to the exact surface: psr no worse than 1.1 x the better of CGAL and PCL, on the
//     Chamfer average and on the 95th-percentile Hausdorff distance (the target).
//     psr is about 0.3-0.4 x CGAL (at comparable resolution) and close to PCL, whose octree and
//     B-splines it shares. With its vertices on the isosurface psr was 1.31 x PCL (Chamfer) on
//     the torus: each flat triangle is a chord of the tight tube, inside it, while PCL's
//     vertices land about 1e-4 outside (its isovalue averages chi over node centres, which on a
//     curved surface offsets it outwards by about the chords' sag). psr's fitted vertices move
//     out by the sag itself, measured per vertex (numbers in docs/comparisons.md).
constexpr double kAreaVolumeRelTol = 0.005;

void check_truth_distance(const char *measure, double psr, double cgal, double pcl) {
    EXPECT_LE(psr, kTarget * std::min(cgal, pcl))
        << measure << " to the exact surface: psr " << psr << ", CGAL " << cgal << ", PCL " << pcl
        << "; psr must be within " << kTarget << " x the better";
}

void check_analytic(const Input &in, const Comparison &c, long long euler) {
    const Measured &psr = c.psr();
    check_closed_manifold(psr, euler);
    EXPECT_NEAR(psr.area / in.shape->area, 1.0, kAreaVolumeRelTol)
        << "area " << psr.area << ", exact " << in.shape->area;
    EXPECT_NEAR(psr.volume / in.shape->volume, 1.0, kAreaVolumeRelTol)
        << "volume " << psr.volume << ", exact " << in.shape->volume;
    check_truth_distance("Chamfer average", psr.to_truth.chamfer_avg(), c.cgal().to_truth.chamfer_avg(),
                         c.pcl().to_truth.chamfer_avg());
    check_truth_distance("95% Hausdorff", psr.to_truth.hausdorff95(), c.cgal().to_truth.hausdorff95(),
                         c.pcl().to_truth.hausdorff95());
    check_agreement("CGAL", c.psr_cgal, c.cell, kSmoothAgreement);
    check_agreement("PCL", c.psr_pcl, c.cell, kSmoothAgreement);
}

// ---------------------------------------------------------------------------------------------
// The analytic shapes, at depth 7 for psr and PCL. 40,000 points put about one sample in each
// depth-7 cell the surface crosses, so both octree methods extract at depth 7 (their vertex
// counts agree within 0.2%; at depth 8 PCL's adaptive octree would stay at depth 7 where the
// points are too sparse while psr's goes to depth 8, and the sizes would no longer compare).
// CGAL's facets are bounded by the same cell (compare()), CGAL's average spacing being about
// 0.9 cell: the three work at comparable resolution.

Input sphere_input() {
    Input in;
    in.order = 1;
    in.name = "sphere";
    // Off-centre so that the surface does not line up with the octree grid.
    in.shape = inputs::sphere({0.013, -0.021, 0.007}, 1.0, 40000, 1);
    in.cloud = in.shape->cloud;
    in.title = "Sphere (analytic), 40,000 points, depth 7";
    in.note = "Unit sphere centred at (0.013, -0.021, 0.007); 40,000 points uniform on it (seed 1), exact "
              "normals, no noise.";
    in.octree.depth = 7;
    return in;
}

Input torus_input() {
    Input in;
    in.order = 2;
    in.name = "torus";
    in.shape = inputs::torus({0.011, 0.017, -0.009}, 1.0, 0.35, 40000, 2);
    in.cloud = in.shape->cloud;
    in.title = "Torus (analytic), 40,000 points, depth 7";
    in.note = "Torus around z centred at (0.011, 0.017, -0.009), radii 1 and 0.35; 40,000 area-uniform points "
              "(seed 2), exact normals, no noise.";
    in.octree.depth = 7;
    return in;
}

} // namespace

TEST(Compare, Sphere) {
    const Input in = sphere_input();
    const Comparison c = compare(in);
    check_analytic(in, c, 2);
}

TEST(Compare, Torus) {
    const Input in = torus_input();
    const Comparison c = compare(in);
    check_analytic(in, c, 0);
}

// ---------------------------------------------------------------------------------------------
// Real point sets, at the depths of the issue. The Euler characteristics are those all three
// methods agree on: the kitten has a handle (genus 1, χ 0), the bunny is a sphere (χ 2).

TEST(Compare, Kitten) {
    LOAD_OR_SKIP(cloud, "kitten_cgal.ply");
    Input in;
    in.order = 3;
    in.name = "kitten";
    in.cloud = *cloud;
    in.title = format("Kitten (CGAL test set), %zu points, depth 7", in.cloud.size());
    in.note = "`kitten_cgal.ply`: CGAL's kitten point set, normals as shipped; all points.";
    in.octree.depth = 7;
    const Comparison c = compare(in);
    check_closed_manifold(c.psr(), 0);
    check_agreement("CGAL", c.psr_cgal, c.cell, kScanAgreement);
    check_agreement("PCL", c.psr_pcl, c.cell, kScanAgreement);
}

// The oni is a closed head, but its 1,435 points leave the bottom of the neck unsampled: there
// the indicator function of both octree methods reaches the face of the reconstruction cube
// (scale 1.1). psr caps the opening on the cube's face and returns a closed genus-0 mesh; PCL
// leaves it open. The methods then differ where there is no data, so agreement is asserted one
// way: PCL's surface must lie near psr's (psr's cap has no counterpart in PCL's mesh). And PCL's
// adaptive octree stays about two levels coarser on so few points (4,378 vertices against
// psr's 42,924 at depth 7), so its own discretisation error is several depth-7 cells: the
// tolerance is twice the scans' (measured 0.20 cell mean). CGAL returns a genus-2 surface well
// off its own input (mean input-to-mesh distance about 0.8 cell, psr's 0.13): psr-CGAL
// agreement is not asserted on this input; psr must instead fit the input better than CGAL.
// One piece is not asserted either: the horn's thin, sparsely sampled tip comes out as a closed
// piece of its own (66 vertices at depth 7) under Neumann boundaries, as it does in Kazhdan's
// PoissonRecon (Open3D 0.20: 2-4 pieces at depths 6-10) and in PCL (2 pieces); with free
// boundaries psr keeps one piece. Asserted: a closed 2-manifold of at most two pieces, each a
// sphere (Euler characteristic 2 per piece).
TEST(Compare, Oni) {
    LOAD_OR_SKIP(cloud, "oni_cgal.ply");
    Input in;
    in.order = 4;
    in.name = "oni";
    in.cloud = *cloud;
    in.title = format("Oni (CGAL test set), %zu points, depth 7", in.cloud.size());
    in.note = "`oni_cgal.ply`: CGAL's oni point set, normals as shipped; all points. The neck's bottom is "
              "unsampled: psr's and PCL's surfaces reach the reconstruction cube there; psr caps the opening "
              "on the cube's face, PCL leaves it open.";
    in.octree.depth = 7;
    const Comparison c = compare(in);
    check_manifold_only(c.psr());
    EXPECT_LE(c.psr().topo.components, 2u);
    EXPECT_EQ(c.psr().topo.euler, 2 * static_cast<long long>(c.psr().topo.components));
    const double cell = c.cell;
    EXPECT_LE(c.psr_pcl.b_to_a.mean, 2 * kScanAgreement.chamfer_avg_cells * cell)
        << "PCL's surface is " << c.psr_pcl.b_to_a.mean / cell << " cells from psr's on average";
    EXPECT_LE(c.psr_pcl.b_to_a.p95, 2 * kScanAgreement.h95_cells * cell)
        << "PCL's surface is " << c.psr_pcl.b_to_a.p95 / cell << " cells from psr's (95th percentile)";
    EXPECT_LT(c.psr().input_to_mesh.mean, c.cgal().input_to_mesh.mean);
}

TEST(Compare, Bunny) {
    LOAD_OR_SKIP(cloud, "bunny_scans.ply");
    Input in;
    in.order = 5;
    in.name = "bunny";
    // CGAL's Delaunay refinement and surface mesher take minutes on all 362,272 points; every
    // fourth point (the same subset for all three methods) keeps the run short and still samples
    // the surface more densely than depth 8 resolves.
    in.cloud = inputs::every_kth(*cloud, 4);
    in.title = format("Stanford bunny (10 raw scans), every 4th of %zu points = %zu, depth 8", cloud->size(),
                      in.cloud.size());
    in.note = "`bunny_scans.ply`: the ten merged range scans, estimated normals; points 0, 4, 8, ... for all "
              "three methods alike.";
    in.octree.depth = 8;
    const Comparison c = compare(in);
    check_closed_manifold(c.psr(), 2);
    check_agreement("CGAL", c.psr_cgal, c.cell, kScanAgreement);
    check_agreement("PCL", c.psr_pcl, c.cell, kScanAgreement);
}
