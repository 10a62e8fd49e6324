// The measuring code checked against closed-form values, so that the comparison tests measure
// what they claim to: topology of small known meshes, area and volume of a cube, area-uniform
// sampling, and BVH distances against brute force.
#include "inputs.hpp"
#include "mesh_metrics.hpp"

#include <gtest/gtest.h>

#include <cmath>
#include <limits>

namespace {

using metrics::Mesh;
using metrics::Vec3;

// The cube [0,2]^3 with 12 outward-facing triangles.
Mesh cube() {
    Mesh m;
    for (int i = 0; i < 8; ++i) m.vertices.push_back({2.0 * (i & 1), 2.0 * ((i >> 1) & 1), 2.0 * ((i >> 2) & 1)});
    m.triangles = {{0, 2, 1}, {1, 2, 3}, {4, 5, 6}, {5, 7, 6}, {0, 1, 4}, {1, 5, 4},
                   {2, 6, 3}, {3, 6, 7}, {0, 4, 2}, {2, 4, 6}, {1, 3, 5}, {3, 7, 5}};
    return m;
}

TEST(MeshMetrics, CubeIsAClosedManifoldWithExactAreaAndVolume) {
    const Mesh m = cube();
    const metrics::Topology t = metrics::topology(m);
    EXPECT_TRUE(t.closed_manifold());
    EXPECT_EQ(t.vertices, 8u);
    EXPECT_EQ(t.edges, 18u);
    EXPECT_EQ(t.euler, 2);
    EXPECT_EQ(t.components, 1u);
    EXPECT_DOUBLE_EQ(metrics::area(m), 24.0);
    EXPECT_DOUBLE_EQ(metrics::signed_volume(m), 8.0);
}

TEST(MeshMetrics, FlippedTriangleIsMisorientedAndVolumeChangesSign) {
    Mesh m = cube();
    std::swap(m.triangles[0][1], m.triangles[0][2]);
    const metrics::Topology t = metrics::topology(m);
    EXPECT_TRUE(t.closed());
    EXPECT_EQ(t.misoriented_edges, 3u);
    EXPECT_FALSE(t.closed_manifold());
    Mesh inward = cube();
    for (auto &f : inward.triangles) std::swap(f[1], f[2]); // consistent again, facing inwards
    EXPECT_TRUE(metrics::topology(inward).closed_manifold());
    EXPECT_DOUBLE_EQ(metrics::signed_volume(inward), -8.0);
}

TEST(MeshMetrics, OpenSquareHasBoundary) {
    Mesh m;
    m.vertices = {{0, 0, 0}, {1, 0, 0}, {1, 1, 0}, {0, 1, 0}};
    m.triangles = {{0, 1, 2}, {0, 2, 3}};
    const metrics::Topology t = metrics::topology(m);
    EXPECT_FALSE(t.closed());
    EXPECT_EQ(t.boundary_edges, 4u);
    EXPECT_EQ(t.euler, 1);
    EXPECT_EQ(t.nonmanifold_vertices, 0u);
}

TEST(MeshMetrics, ThreeTrianglesOnAnEdgeAndABowTie) {
    Mesh fin;
    fin.vertices = {{0, 0, 0}, {1, 0, 0}, {0, 1, 0}, {0, -1, 0}, {0, 0, 1}};
    fin.triangles = {{0, 1, 2}, {1, 0, 3}, {0, 1, 4}};
    EXPECT_EQ(metrics::topology(fin).nonmanifold_edges, 1u);

    Mesh bowtie; // two triangles sharing only vertex 0
    bowtie.vertices = {{0, 0, 0}, {1, 0, 0}, {1, 1, 0}, {-1, 0, 0}, {-1, -1, 0}, {5, 5, 5}};
    bowtie.triangles = {{0, 1, 2}, {0, 3, 4}};
    const metrics::Topology t = metrics::topology(bowtie);
    EXPECT_EQ(t.nonmanifold_vertices, 1u);
    EXPECT_EQ(t.nonmanifold_edges, 0u);
    EXPECT_EQ(t.components, 1u);
    EXPECT_EQ(t.unreferenced, 1u);
}

TEST(MeshMetrics, TwoCubesAreTwoComponents) {
    Mesh m = cube();
    const Mesh b = cube();
    for (const Vec3 &v : b.vertices) m.vertices.push_back({v[0] + 5, v[1], v[2]});
    for (const auto &f : b.triangles) m.triangles.push_back({f[0] + 8, f[1] + 8, f[2] + 8});
    const metrics::Topology t = metrics::topology(m);
    EXPECT_EQ(t.components, 2u);
    EXPECT_EQ(t.euler, 4);
    EXPECT_DOUBLE_EQ(metrics::signed_volume(m), 16.0);
}

TEST(MeshMetrics, SamplesAreOnTheSurfaceAndAreaUniform) {
    const Mesh m = cube();
    const auto samples = metrics::sample_surface(m, 60000, 3);
    ASSERT_EQ(samples.size(), 60000u);
    int on_face_z0 = 0;
    for (const Vec3 &p : samples) {
        double d = std::numeric_limits<double>::infinity();
        for (int k = 0; k < 3; ++k) d = std::min({d, std::abs(p[k]), std::abs(p[k] - 2.0)});
        ASSERT_LT(d, 1e-12);
        if (std::abs(p[2]) < 1e-12) ++on_face_z0;
    }
    // One face in six; binomial standard deviation sqrt(60000 * 1/6 * 5/6) = 91.
    EXPECT_NEAR(on_face_z0, 10000, 400);
    EXPECT_EQ(samples, metrics::sample_surface(m, 60000, 3)); // fixed seed, same samples
}

TEST(MeshMetrics, SamplesDoNotDependOnElementOrder) {
    const Mesh m = cube();
    Mesh shuffled; // vertices reversed, triangles reversed and rotated
    const std::uint32_t n = static_cast<std::uint32_t>(m.vertices.size());
    for (std::uint32_t i = 0; i < n; ++i) shuffled.vertices.push_back(m.vertices[n - 1 - i]);
    for (auto it = m.triangles.rbegin(); it != m.triangles.rend(); ++it)
        shuffled.triangles.push_back({n - 1 - (*it)[1], n - 1 - (*it)[2], n - 1 - (*it)[0]});
    EXPECT_EQ(metrics::sample_surface(metrics::canonical(m), 1000, 5),
              metrics::sample_surface(metrics::canonical(shuffled), 1000, 5));
    EXPECT_DOUBLE_EQ(metrics::signed_volume(shuffled), 8.0);
}

TEST(MeshMetrics, PointTriangleDistanceInEveryRegion) {
    const Vec3 a{0, 0, 0}, b{1, 0, 0}, c{0, 1, 0};
    EXPECT_DOUBLE_EQ(metrics::point_triangle_squared_distance({0.2, 0.2, 3}, a, b, c), 9.0);  // face
    EXPECT_DOUBLE_EQ(metrics::point_triangle_squared_distance({-1, -1, 0}, a, b, c), 2.0);   // vertex a
    EXPECT_DOUBLE_EQ(metrics::point_triangle_squared_distance({2, 0, 1}, a, b, c), 2.0);     // vertex b
    EXPECT_DOUBLE_EQ(metrics::point_triangle_squared_distance({0, 3, 0}, a, b, c), 4.0);     // vertex c
    EXPECT_DOUBLE_EQ(metrics::point_triangle_squared_distance({0.5, -2, 0}, a, b, c), 4.0);  // edge ab
    EXPECT_DOUBLE_EQ(metrics::point_triangle_squared_distance({-3, 0.5, 0}, a, b, c), 9.0);  // edge ac
    EXPECT_NEAR(metrics::point_triangle_squared_distance({1, 1, 0}, a, b, c), 0.5, 1e-15);   // edge bc
}

TEST(MeshMetrics, BvhDistanceMatchesBruteForce) {
    // A coarse triangulated sphere (latitude-longitude grid) and points around it.
    Mesh m;
    const int nu = 24, nv = 12;
    m.vertices.push_back({0, 0, 1});
    for (int j = 1; j < nv; ++j)
        for (int i = 0; i < nu; ++i) {
            const double th = inputs::kPi * j / nv, ph = 2 * inputs::kPi * i / nu;
            m.vertices.push_back({std::sin(th) * std::cos(ph), std::sin(th) * std::sin(ph), std::cos(th)});
        }
    m.vertices.push_back({0, 0, -1});
    const auto ring = [&](int j, int i) { return static_cast<std::uint32_t>(1 + (j - 1) * nu + (i % nu)); };
    const std::uint32_t south = static_cast<std::uint32_t>(m.vertices.size() - 1);
    for (int i = 0; i < nu; ++i) {
        m.triangles.push_back({0, ring(1, i), ring(1, i + 1)});
        m.triangles.push_back({south, ring(nv - 1, i + 1), ring(nv - 1, i)});
        for (int j = 1; j < nv - 1; ++j) {
            m.triangles.push_back({ring(j, i), ring(j + 1, i), ring(j + 1, i + 1)});
            m.triangles.push_back({ring(j, i), ring(j + 1, i + 1), ring(j, i + 1)});
        }
    }
    const metrics::Topology t = metrics::topology(m);
    ASSERT_TRUE(t.closed_manifold());
    ASSERT_EQ(t.euler, 2);

    const metrics::SurfaceDistance bvh(m);
    metrics::Rng rng(11);
    for (int s = 0; s < 2000; ++s) {
        const Vec3 p{3 * rng.uniform() - 1.5, 3 * rng.uniform() - 1.5, 3 * rng.uniform() - 1.5};
        double brute = std::numeric_limits<double>::infinity();
        for (const auto &f : m.triangles)
            brute = std::min(brute, metrics::point_triangle_squared_distance(p, m.vertices[f[0]], m.vertices[f[1]],
                                                                             m.vertices[f[2]]));
        ASSERT_DOUBLE_EQ(bvh.squared_distance(p), brute);
    }
}

TEST(MeshMetrics, SummaryPercentileAndChamfer) {
    std::vector<double> d;
    for (int i = 1; i <= 100; ++i) d.push_back(i);
    const metrics::OneSided s = metrics::summarize(d);
    EXPECT_DOUBLE_EQ(s.mean, 50.5);
    EXPECT_DOUBLE_EQ(s.p95, 95.0);
    EXPECT_DOUBLE_EQ(s.max, 100.0);
    const metrics::Symmetric sym{s, metrics::summarize({1.0, 3.0})};
    EXPECT_DOUBLE_EQ(sym.chamfer_sum(), 52.5);
    EXPECT_DOUBLE_EQ(sym.chamfer_avg(), 26.25);
    EXPECT_DOUBLE_EQ(sym.hausdorff95(), 95.0);
}

TEST(Inputs, AnalyticShapesAreExact) {
    const inputs::Shape s = inputs::sphere({1, 2, 3}, 2.0, 1000, 5);
    for (std::size_t i = 0; i < s.cloud.size(); ++i) {
        EXPECT_LT(s.distance(s.cloud.positions[i]), 1e-12);
        EXPECT_NEAR(metrics::norm(s.cloud.normals[i]), 1.0, 1e-12);
    }
    const inputs::Shape t = inputs::torus({0, 0, 1}, 1.0, 0.25, 1000, 6);
    for (std::size_t i = 0; i < t.cloud.size(); ++i) {
        EXPECT_LT(t.distance(t.cloud.positions[i]), 1e-12);
        // The normal points away from the tube's core circle.
        const Vec3 q = t.cloud.positions[i] - Vec3{0, 0, 1};
        const double rho = std::hypot(q[0], q[1]);
        const Vec3 core{q[0] / rho, q[1] / rho, 0.0};
        const Vec3 out = q - core;
        EXPECT_GT(metrics::dot(out, t.cloud.normals[i]), 0.24);
    }
    for (const Vec3 &p : t.sample(1000, 9)) EXPECT_LT(t.distance(p), 1e-12);
    EXPECT_NEAR(t.area, 4 * inputs::kPi * inputs::kPi * 0.25, 1e-12);
}

} // namespace
