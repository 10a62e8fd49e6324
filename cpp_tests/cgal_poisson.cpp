// CGAL's Poisson reconstruction (CGAL 5.5, Poisson_surface_reconstruction_3): the implicit
// function is solved on a Delaunay refinement of the input points, then meshed by the surface
// mesher. The steps are those of CGAL::poisson_surface_reconstruction_delaunay(), written out so
// that every parameter, including the ones that function hides, is set here.
#include "reconstructors.hpp"

#include <CGAL/Complex_2_in_triangulation_3.h>
#include <CGAL/Eigen_solver_traits.h>
#include <CGAL/Exact_predicates_inexact_constructions_kernel.h>
#include <CGAL/IO/facets_in_complex_2_to_triangle_mesh.h>
#include <CGAL/Implicit_surface_3.h>
#include <CGAL/Poisson_reconstruction_function.h>
#include <CGAL/Random.h>
#include <CGAL/Surface_mesh.h>
#include <CGAL/Surface_mesh_default_criteria_3.h>
#include <CGAL/Surface_mesh_default_triangulation_3.h>
#include <CGAL/compute_average_spacing.h>
#include <CGAL/make_surface_mesh.h>
#include <CGAL/property_map.h>
#include <CGAL/version.h>

#include <chrono>
#include <cmath>
#include <sstream>
#include <stdexcept>
#include <utility>
#include <vector>

#ifndef CGAL_EIGEN3_ENABLED
#error "CGAL's Poisson solver needs Eigen: build with CGAL_EIGEN3_ENABLED (CMakeLists.txt does)"
#endif

namespace recon {
namespace {

using Kernel = CGAL::Exact_predicates_inexact_constructions_kernel;
using Point = Kernel::Point_3;
using Vector = Kernel::Vector_3;
using PointWithNormal = std::pair<Point, Vector>;
using PointMap = CGAL::First_of_pair_property_map<PointWithNormal>;
using NormalMap = CGAL::Second_of_pair_property_map<PointWithNormal>;
using Function = CGAL::Poisson_reconstruction_function<Kernel>;
using Triangulation = CGAL::Surface_mesh_default_triangulation_3;
using Complex = CGAL::Surface_mesh_complex_2_in_triangulation_3<Triangulation>;
using Surface = CGAL::Implicit_surface_3<Kernel, Function>;
using Solver = CGAL::Eigen_solver_traits<
    Eigen::ConjugateGradient<CGAL::Eigen_sparse_symmetric_matrix<double>::EigenType>>;

} // namespace

Result run_cgal(const inputs::Cloud &cloud, const CgalParams &p) {
    std::vector<PointWithNormal> points;
    points.reserve(cloud.size());
    for (std::size_t i = 0; i < cloud.size(); ++i)
        points.emplace_back(Point(cloud.positions[i][0], cloud.positions[i][1], cloud.positions[i][2]),
                            Vector(cloud.normals[i][0], cloud.normals[i][1], cloud.normals[i][2]));

    // The surface mesher draws its initial points from CGAL's default generator, which is seeded
    // from the clock: a fixed seed makes the output repeatable.
    CGAL::get_default_random() = CGAL::Random(p.seed);

    Result out;
    const auto t0 = std::chrono::steady_clock::now();

    // The size parameter everything else is relative to: the mean distance to the k nearest
    // neighbours (k = 6 as in CGAL's Poisson examples).
    const double spacing = CGAL::compute_average_spacing<CGAL::Sequential_tag>(
        points, p.spacing_neighbors, CGAL::parameters::point_map(PointMap()));

    // The implicit function with CGAL's defaults, all spelt out:
    //   solver: Eigen's conjugate gradient (CGAL's default), tolerance Eigen's default (machine
    //     epsilon) and its default iteration cap (twice the number of unknowns, which only the
    //     solver knows);
    //   approximation_ratio 0 and average_spacing_ratio 5: no "smoother hole filling" pass
    //     (compute_implicit_function(false), the default of poisson_surface_reconstruction_delaunay).
    // The function is then shifted so that the median of its values at the inputs is 0.
    Function function(points.begin(), points.end(), PointMap(), NormalMap());
    Solver solver;
    solver.solver().setTolerance(Eigen::NumTraits<double>::epsilon());
    if (!function.compute_implicit_function(solver, CGAL::Poisson_visitor(), /*approximation_ratio=*/0.0,
                                            /*average_spacing_ratio=*/5.0))
        throw std::runtime_error("CGAL: compute_implicit_function failed");

    // The surface mesher, as in poisson_surface_reconstruction_delaunay(): the function is
    // restricted to a ball 5 times the input's bounding sphere around an inner point, the
    // intersections are found by bisection to sm_distance x spacing / 1000, and the facet
    // criteria are an angle bound, a size bound and a distance bound (the values of CGAL's
    // examples, in CgalParams). Manifold_with_boundary_tag is that function's default tag; the
    // mesher starts from 20 initial points (make_surface_mesh's default). The radius bound is
    // either sm_radius x spacing (CGAL's rule) or an absolute facet_radius (see CgalParams).
    const Point inner = function.get_inner_point();
    const double radius = std::sqrt(function.bounding_sphere().squared_radius());
    const double sphere_radius = 5.0 * radius;
    const double dichotomy_error = p.sm_distance * spacing / 1000.0;
    Surface surface(function, Kernel::Sphere_3(inner, sphere_radius * sphere_radius), dichotomy_error / sphere_radius);
    const double radius_bound = p.facet_radius > 0.0 ? p.facet_radius : p.sm_radius * spacing;
    CGAL::Surface_mesh_default_criteria_3<Triangulation> criteria(p.sm_angle, radius_bound, p.sm_distance * spacing);
    Triangulation tr;
    Complex c2t3(tr);
    CGAL::make_surface_mesh(c2t3, surface, criteria, CGAL::Manifold_with_boundary_tag(), /*initial points=*/20);
    if (tr.number_of_vertices() == 0) throw std::runtime_error("CGAL: the surface mesher found no surface");
    CGAL::Surface_mesh<Point> mesh;
    CGAL::facets_in_complex_2_to_triangle_mesh(c2t3, mesh);
    out.seconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();

    // Surface_mesh indices are dense after a fresh build (no removed elements).
    out.mesh.vertices.reserve(mesh.number_of_vertices());
    for (auto v : mesh.vertices()) {
        const Point &q = mesh.point(v);
        out.mesh.vertices.push_back({q.x(), q.y(), q.z()});
    }
    out.mesh.triangles.reserve(mesh.number_of_faces());
    for (auto f : mesh.faces()) {
        metrics::Tri t{};
        int k = 0;
        for (auto v : CGAL::vertices_around_face(mesh.halfedge(f), mesh)) {
            if (k == 3) throw std::runtime_error("CGAL returned a face that is not a triangle");
            t[k++] = static_cast<std::uint32_t>(v.idx());
        }
        out.mesh.triangles.push_back(t);
    }

    std::ostringstream s;
    s << "CGAL " << CGAL_VERSION_STR << " Poisson_reconstruction_function + make_surface_mesh: average spacing "
      << spacing << " (k " << p.spacing_neighbors << "), Eigen CG (tolerance eps), approximation_ratio 0, "
      << "average_spacing_ratio 5, sm_angle " << p.sm_angle << ", facet radius bound " << radius_bound << " (= "
      << radius_bound / spacing << " x spacing), sm_distance "
      << p.sm_distance << ", Manifold_with_boundary_tag, 20 initial points, seed " << p.seed;
    out.settings = s.str();
    return out;
}

} // namespace recon
