// The three Poisson reconstructions under comparison, each behind one function taking the same
// oriented points and returning the same mesh type, the wall-clock time of the reconstruction
// call and a one-line record of every parameter it was given.
//
// Each lives in its own translation unit (psr_poisson.cpp, cgal_poisson.cpp, pcl_poisson.cpp):
// CGAL and PCL headers are heavy, and separate units compile in parallel.
#pragma once

#include "inputs.hpp"
#include "mesh_metrics.hpp"

#include <cstdint>
#include <string>

namespace recon {

struct Result {
    metrics::Mesh mesh;
    double seconds = 0.0;  // the reconstruction call alone (not input conversion or measuring)
    std::string settings;  // every parameter, for the log and docs/comparisons.md
};

// Octree parameters shared by psr and PCL (both are octree B-spline solvers of the screened
// Poisson equation with degree-2 B-splines, so the same numbers mean the same thing).
struct OctreeParams {
    unsigned depth = 8;             // finest octree depth
    unsigned full_depth = 5;        // complete octree down to this depth (PCL: min depth)
    float samples_per_node = 1.5f;  // PoissonRecon's default
    float scale = 1.1f;             // reconstruction cube / bounding box
    float point_weight = 4.0f;      // screening weight alpha
    unsigned threads = 1;           // one thread each: CGAL's reconstruction is sequential
};

// psr through its C API (psr.h). Throws std::runtime_error with psr's message on failure.
Result run_psr(const inputs::Cloud &cloud, const OctreeParams &p);

// PCL 1.13's pcl::Poisson<pcl::PointNormal> (Kazhdan's PoissonRecon, version 4 family).
Result run_pcl(const inputs::Cloud &cloud, const OctreeParams &p);

// CGAL 5.5's Delaunay-based Poisson reconstruction: Poisson_reconstruction_function and the
// surface mesher, the steps of poisson_surface_reconstruction_delaunay() spelt out so that every
// parameter is visible.
struct CgalParams {
    unsigned spacing_neighbors = 6; // k of compute_average_spacing (CGAL's examples use 6)
    double sm_angle = 20.0;         // minimum facet angle, degrees
    double sm_radius = 30.0;        // maximum surface Delaunay ball radius, x average spacing
    double sm_distance = 0.375;     // maximum centre-to-centre distance, x average spacing
    // When positive, the maximum surface Delaunay ball radius in input units, replacing
    // sm_radius x spacing: the tests set it to the octree cell width of psr's and PCL's depth so
    // that CGAL's triangles are as fine as theirs (comparable resolution).
    double facet_radius = 0.0;
    std::uint32_t seed = 42;        // CGAL's default random generator is seeded from the clock
};
Result run_cgal(const inputs::Cloud &cloud, const CgalParams &p);

} // namespace recon
