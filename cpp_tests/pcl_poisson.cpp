// PCL's Poisson reconstruction (pcl::Poisson<pcl::PointNormal>, PCL 1.13).
#include "reconstructors.hpp"

#include <pcl/point_cloud.h>
#include <pcl/point_types.h>
#include <pcl/surface/poisson.h>

#include <chrono>
#include <sstream>
#include <stdexcept>

namespace recon {

Result run_pcl(const inputs::Cloud &cloud, const OctreeParams &p) {
    auto input = pcl::make_shared<pcl::PointCloud<pcl::PointNormal>>();
    input->resize(cloud.size());
    for (std::size_t i = 0; i < cloud.size(); ++i) {
        pcl::PointNormal &q = (*input)[i];
        q.x = static_cast<float>(cloud.positions[i][0]);
        q.y = static_cast<float>(cloud.positions[i][1]);
        q.z = static_cast<float>(cloud.positions[i][2]);
        q.normal_x = static_cast<float>(cloud.normals[i][0]);
        q.normal_y = static_cast<float>(cloud.normals[i][1]);
        q.normal_z = static_cast<float>(cloud.normals[i][2]);
        q.curvature = 0.0f;
    }

    // Every parameter set. PCL's defaults (pcl/surface/impl/poisson.hpp in 1.13.0: depth 8,
    // min depth 5, point weight 4, scale 1.1, samples per node 1.0, degree 2, one thread) differ
    // from PoissonRecon's and psr's in samples per node (1.0 against 1.5), so the octree
    // parameters are psr's, which are PoissonRecon's (OctreeParams): depth, min depth (= full
    // depth), samples per node, scale, point weight (screening), threads. PCL fixes its kernel
    // depth at depth - 2, as psr is told to.
    // The rest are PCL-specific and kept at values that give PoissonRecon's behaviour:
    //   degree 2      - the B-spline degree psr uses (and PCL's default);
    //   solver divide, iso divide 8 - depths from which PCL solves / extracts block by block to
    //                   save memory; at depth <= 8 nothing is divided (PCL's defaults);
    //   confidence off - the inputs carry no confidence, normals are unit length;
    //   manifold on   - polygons from the marching cubes are split with a centroid vertex, which
    //                   keeps the mesh manifold (PCL's default);
    //   output polygons off - triangles, as psr and CGAL return.
    pcl::Poisson<pcl::PointNormal> poisson;
    poisson.setDepth(static_cast<int>(p.depth));
    poisson.setMinDepth(static_cast<int>(p.full_depth));
    poisson.setSamplesPerNode(p.samples_per_node);
    poisson.setScale(p.scale);
    poisson.setPointWeight(p.point_weight);
    poisson.setThreads(static_cast<int>(p.threads));
    poisson.setDegree(2);
    poisson.setSolverDivide(8);
    poisson.setIsoDivide(8);
    poisson.setConfidence(false);
    poisson.setManifold(true);
    poisson.setOutputPolygons(false);
    poisson.setInputCloud(input);

    pcl::PointCloud<pcl::PointNormal> vertices;
    std::vector<pcl::Vertices> polygons;
    Result out;
    const auto t0 = std::chrono::steady_clock::now();
    poisson.reconstruct(vertices, polygons);
    out.seconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();

    out.mesh.vertices.resize(vertices.size());
    for (std::size_t i = 0; i < vertices.size(); ++i) out.mesh.vertices[i] = {vertices[i].x, vertices[i].y, vertices[i].z};
    out.mesh.triangles.reserve(polygons.size());
    for (const pcl::Vertices &poly : polygons) {
        if (poly.vertices.size() != 3) throw std::runtime_error("PCL returned a polygon that is not a triangle");
        metrics::Tri t{};
        for (int k = 0; k < 3; ++k) {
            if (poly.vertices[k] < 0 || static_cast<std::size_t>(poly.vertices[k]) >= vertices.size())
                throw std::runtime_error("PCL returned a vertex index out of range");
            t[k] = static_cast<std::uint32_t>(poly.vertices[k]);
        }
        out.mesh.triangles.push_back(t);
    }

    std::ostringstream s;
    s << "PCL " << PCL_VERSION_PRETTY << " pcl::Poisson<PointNormal>: depth " << p.depth << ", min_depth "
      << p.full_depth << ", samples_per_node " << p.samples_per_node << ", scale " << p.scale << ", point_weight "
      << p.point_weight << ", threads " << p.threads
      << ", degree 2, solver_divide 8, iso_divide 8, confidence off, manifold on, output_polygons off";
    out.settings = s.str();
    return out;
}

} // namespace recon
