// Mesh measurements shared by every reconstruction in the comparison tests, so psr, CGAL and PCL
// are measured by the same code: topology (closedness, manifoldness, orientation, components,
// Euler characteristic), area and enclosed volume, area-uniform surface samples drawn with a
// fixed seed, and sample-to-surface distances through a bounding-volume hierarchy over the
// triangles (exact point-to-triangle distances, not distances to the other mesh's vertices).
//
// Header-only, C++17, no dependency beyond the standard library.
#pragma once

#include <algorithm>
#include <array>
#include <cmath>
#include <cstddef>
#include <cstdint>
#include <functional>
#include <limits>
#include <numeric>
#include <random>
#include <stdexcept>
#include <string>
#include <unordered_map>
#include <utility>
#include <vector>

namespace metrics {

// A point or vector (a struct of its own so that the operators below are found by
// argument-dependent lookup from any namespace).
struct Vec3 {
    double c[3];
    double &operator[](std::size_t k) { return c[k]; }
    double operator[](std::size_t k) const { return c[k]; }
    bool operator==(const Vec3 &o) const { return c[0] == o.c[0] && c[1] == o.c[1] && c[2] == o.c[2]; }
};
using Tri = std::array<std::uint32_t, 3>;

inline Vec3 operator+(const Vec3 &a, const Vec3 &b) { return {a[0] + b[0], a[1] + b[1], a[2] + b[2]}; }
inline Vec3 operator-(const Vec3 &a, const Vec3 &b) { return {a[0] - b[0], a[1] - b[1], a[2] - b[2]}; }
inline Vec3 operator*(double s, const Vec3 &a) { return {s * a[0], s * a[1], s * a[2]}; }
inline double dot(const Vec3 &a, const Vec3 &b) { return a[0] * b[0] + a[1] * b[1] + a[2] * b[2]; }
inline Vec3 cross(const Vec3 &a, const Vec3 &b) {
    return {a[1] * b[2] - a[2] * b[1], a[2] * b[0] - a[0] * b[2], a[0] * b[1] - a[1] * b[0]};
}
inline double norm(const Vec3 &a) { return std::sqrt(dot(a, a)); }

// A triangle mesh as every reconstructor's output is converted to: positions in the input's
// coordinates and triangles as vertex index triples.
struct Mesh {
    std::vector<Vec3> vertices;
    std::vector<Tri> triangles;
};

// An axis-aligned box.
struct Box {
    Vec3 lo{std::numeric_limits<double>::infinity(), std::numeric_limits<double>::infinity(),
            std::numeric_limits<double>::infinity()};
    Vec3 hi{-std::numeric_limits<double>::infinity(), -std::numeric_limits<double>::infinity(),
            -std::numeric_limits<double>::infinity()};
    void add(const Vec3 &p) {
        for (int k = 0; k < 3; ++k) {
            lo[k] = std::min(lo[k], p[k]);
            hi[k] = std::max(hi[k], p[k]);
        }
    }
    double diagonal() const { return norm(hi - lo); }
    // Squared distance from p to the box (0 inside).
    double squared_distance(const Vec3 &p) const {
        double d2 = 0.0;
        for (int k = 0; k < 3; ++k) {
            const double e = p[k] < lo[k] ? lo[k] - p[k] : (p[k] > hi[k] ? p[k] - hi[k] : 0.0);
            d2 += e * e;
        }
        return d2;
    }
};

inline Box bounding_box(const std::vector<Vec3> &points) {
    Box b;
    for (const Vec3 &p : points) b.add(p);
    return b;
}

// ---------------------------------------------------------------------------------------------
// Topology

struct Topology {
    std::size_t vertices = 0;          // vertices referenced by at least one triangle
    std::size_t unreferenced = 0;      // vertices no triangle uses
    std::size_t edges = 0;             // distinct undirected edges
    std::size_t triangles = 0;
    std::size_t degenerate = 0;        // triangles with a repeated vertex index
    std::size_t boundary_edges = 0;    // edges with one incident triangle
    std::size_t nonmanifold_edges = 0; // edges with three or more incident triangles
    std::size_t nonmanifold_vertices = 0; // vertices whose triangles form more than one fan
    std::size_t misoriented_edges = 0; // two-triangle edges traversed the same way by both
    std::size_t components = 0;        // edge-connected components of the triangles
    long long euler = 0;               // V - E + F over referenced vertices

    // Every edge shared by exactly two triangles (and no degenerate triangle).
    bool closed() const { return boundary_edges == 0 && nonmanifold_edges == 0 && degenerate == 0; }
    // A closed, oriented 2-manifold: closed, every vertex a single fan, orientations agree.
    bool closed_manifold() const {
        return closed() && nonmanifold_vertices == 0 && misoriented_edges == 0 && triangles > 0;
    }
};

namespace detail {
inline std::uint64_t edge_key(std::uint32_t a, std::uint32_t b) {
    if (a > b) std::swap(a, b);
    return (static_cast<std::uint64_t>(a) << 32) | b;
}

struct DisjointSets {
    std::vector<std::uint32_t> parent;
    explicit DisjointSets(std::size_t n) : parent(n) { std::iota(parent.begin(), parent.end(), 0u); }
    std::uint32_t find(std::uint32_t x) {
        while (parent[x] != x) {
            parent[x] = parent[parent[x]];
            x = parent[x];
        }
        return x;
    }
    void unite(std::uint32_t a, std::uint32_t b) {
        a = find(a);
        b = find(b);
        if (a != b) parent[std::max(a, b)] = std::min(a, b);
    }
};
} // namespace detail

inline Topology topology(const Mesh &mesh) {
    Topology t;
    const std::size_t nv = mesh.vertices.size();
    t.triangles = mesh.triangles.size();
    for (const Tri &f : mesh.triangles)
        for (std::uint32_t v : f)
            if (v >= nv) throw std::out_of_range("triangle refers to vertex " + std::to_string(v));

    // Per undirected edge: number of incident triangles and the balance of its directions
    // (+1 for a->b with a<b, -1 for b->a); a consistently oriented interior edge has balance 0.
    struct EdgeInfo {
        std::uint32_t count = 0;
        int balance = 0;
    };
    std::unordered_map<std::uint64_t, EdgeInfo> edges;
    edges.reserve(mesh.triangles.size() * 2);
    std::vector<char> used(nv, 0);
    for (const Tri &f : mesh.triangles) {
        if (f[0] == f[1] || f[1] == f[2] || f[0] == f[2]) {
            ++t.degenerate;
            continue;
        }
        for (int k = 0; k < 3; ++k) {
            const std::uint32_t a = f[k], b = f[(k + 1) % 3];
            EdgeInfo &e = edges[detail::edge_key(a, b)];
            ++e.count;
            e.balance += a < b ? 1 : -1;
            used[a] = 1;
        }
    }
    t.edges = edges.size();
    for (const auto &kv : edges) {
        if (kv.second.count == 1) ++t.boundary_edges;
        if (kv.second.count >= 3) ++t.nonmanifold_edges;
        if (kv.second.count == 2 && kv.second.balance != 0) ++t.misoriented_edges;
    }
    t.vertices = static_cast<std::size_t>(std::count(used.begin(), used.end(), 1));
    t.unreferenced = nv - t.vertices;
    t.euler = static_cast<long long>(t.vertices) - static_cast<long long>(t.edges) +
              static_cast<long long>(t.triangles - t.degenerate);

    // Components: union the vertices of each triangle.
    detail::DisjointSets vsets(nv);
    for (const Tri &f : mesh.triangles) {
        vsets.unite(f[0], f[1]);
        vsets.unite(f[1], f[2]);
    }
    for (std::uint32_t v = 0; v < nv; ++v)
        if (used[v] && vsets.find(v) == v) ++t.components;

    // Non-manifold vertices: the triangles around v, linked when they share an edge through v,
    // must form one fan. Incidence lists in compressed rows.
    std::vector<std::uint32_t> start(nv + 1, 0);
    for (const Tri &f : mesh.triangles)
        for (std::uint32_t v : f) ++start[v + 1];
    std::partial_sum(start.begin(), start.end(), start.begin());
    std::vector<std::uint32_t> incident(start[nv]);
    {
        std::vector<std::uint32_t> fill(start.begin(), start.end() - 1);
        for (std::uint32_t i = 0; i < mesh.triangles.size(); ++i)
            for (std::uint32_t v : mesh.triangles[i]) incident[fill[v]++] = i;
    }
    for (std::uint32_t v = 0; v < nv; ++v) {
        const std::uint32_t b = start[v], e = start[v + 1];
        if (e - b < 2) continue;
        detail::DisjointSets local(e - b);
        for (std::uint32_t i = b; i < e; ++i)
            for (std::uint32_t j = i + 1; j < e; ++j) {
                const Tri &fi = mesh.triangles[incident[i]];
                const Tri &fj = mesh.triangles[incident[j]];
                bool share = false; // another vertex than v in common: an edge through v
                for (std::uint32_t a : fi)
                    for (std::uint32_t c : fj)
                        if (a == c && a != v) share = true;
                if (share) local.unite(i - b, j - b);
            }
        std::size_t fans = 0;
        for (std::uint32_t i = 0; i < e - b; ++i)
            if (local.find(i) == i) ++fans;
        if (fans > 1) ++t.nonmanifold_vertices;
    }
    return t;
}

// ---------------------------------------------------------------------------------------------
// Area and volume

inline double triangle_area(const Mesh &m, const Tri &f) {
    return 0.5 * norm(cross(m.vertices[f[1]] - m.vertices[f[0]], m.vertices[f[2]] - m.vertices[f[0]]));
}

inline double area(const Mesh &m) {
    double a = 0.0;
    for (const Tri &f : m.triangles) a += triangle_area(m, f);
    return a;
}

// Signed enclosed volume by the divergence theorem (sum of signed tetrahedra to a reference
// point): positive when the triangles are oriented outwards. Exact for closed meshes; the
// reference point is the bounding-box centre so that open meshes are less sensitive to it.
inline double signed_volume(const Mesh &m) {
    const Box box = bounding_box(m.vertices);
    const Vec3 c = 0.5 * (box.lo + box.hi);
    double v = 0.0;
    for (const Tri &f : m.triangles)
        v += dot(m.vertices[f[0]] - c, cross(m.vertices[f[1]] - c, m.vertices[f[2]] - c));
    return v / 6.0;
}

// ---------------------------------------------------------------------------------------------
// Deterministic random numbers: std::mt19937_64's sequence is fixed by the standard, but the
// standard distributions are not, so the conversion to doubles is done here.

class Rng {
public:
    explicit Rng(std::uint64_t seed) : engine_(seed) {}
    double uniform() { return static_cast<double>(engine_() >> 11) * 0x1.0p-53; } // [0, 1)
    double normal() { // Box-Muller, one value per call
        double u = uniform();
        while (u <= 0.0) u = uniform();
        const double v = uniform();
        return std::sqrt(-2.0 * std::log(u)) * std::cos(2.0 * 3.14159265358979323846 * v);
    }

private:
    std::mt19937_64 engine_;
};

// The same mesh with its vertices sorted by position and its triangles sorted (each rotated to
// start at its smallest index, orientation kept): two meshes with the same geometry but their
// elements in another order (CGAL's output order follows memory addresses) become identical.
inline Mesh canonical(const Mesh &m) {
    std::vector<std::uint32_t> order(m.vertices.size());
    std::iota(order.begin(), order.end(), 0u);
    const auto less = [&](std::uint32_t a, std::uint32_t b) {
        const Vec3 &p = m.vertices[a], &q = m.vertices[b];
        return std::lexicographical_compare(p.c, p.c + 3, q.c, q.c + 3);
    };
    std::stable_sort(order.begin(), order.end(), less);
    std::vector<std::uint32_t> rank(m.vertices.size());
    Mesh out;
    out.vertices.reserve(m.vertices.size());
    for (std::uint32_t i = 0; i < order.size(); ++i) {
        rank[order[i]] = i;
        out.vertices.push_back(m.vertices[order[i]]);
    }
    out.triangles.reserve(m.triangles.size());
    for (const Tri &f : m.triangles) {
        Tri t{rank[f[0]], rank[f[1]], rank[f[2]]};
        while (t[0] > t[1] || t[0] > t[2]) t = {t[1], t[2], t[0]};
        out.triangles.push_back(t);
    }
    std::sort(out.triangles.begin(), out.triangles.end());
    return out;
}

// n points uniformly distributed over the surface (probability proportional to area), from a
// fixed seed: the same mesh gives the same samples (the same geometry in another element order
// does too after canonical()).
inline std::vector<Vec3> sample_surface(const Mesh &m, std::size_t n, std::uint64_t seed) {
    std::vector<double> cumulative(m.triangles.size());
    double total = 0.0;
    for (std::size_t i = 0; i < m.triangles.size(); ++i) {
        total += triangle_area(m, m.triangles[i]);
        cumulative[i] = total;
    }
    std::vector<Vec3> out;
    if (total <= 0.0) return out;
    out.reserve(n);
    Rng rng(seed);
    for (std::size_t s = 0; s < n; ++s) {
        const double target = rng.uniform() * total;
        std::size_t i = static_cast<std::size_t>(
            std::upper_bound(cumulative.begin(), cumulative.end(), target) - cumulative.begin());
        i = std::min(i, cumulative.size() - 1);
        const Tri &f = m.triangles[i];
        // Uniform in the triangle: (1 - sqrt(r1), sqrt(r1)(1 - r2), sqrt(r1) r2).
        const double r1 = std::sqrt(rng.uniform()), r2 = rng.uniform();
        const Vec3 &a = m.vertices[f[0]], &b = m.vertices[f[1]], &c = m.vertices[f[2]];
        out.push_back((1.0 - r1) * a + (r1 * (1.0 - r2)) * b + (r1 * r2) * c);
    }
    return out;
}

// ---------------------------------------------------------------------------------------------
// Point-to-triangle distance and a BVH over a mesh's triangles

// Squared distance from p to the triangle abc, by the Voronoi region of p: a vertex, an edge or
// the face (the region tests use the barycentric coordinates of p's projection).
inline double point_triangle_squared_distance(const Vec3 &p, const Vec3 &a, const Vec3 &b, const Vec3 &c) {
    const Vec3 ab = b - a, ac = c - a, ap = p - a;
    const double d1 = dot(ab, ap), d2 = dot(ac, ap);
    if (d1 <= 0.0 && d2 <= 0.0) return dot(ap, ap); // vertex a
    const Vec3 bp = p - b;
    const double d3 = dot(ab, bp), d4 = dot(ac, bp);
    if (d3 >= 0.0 && d4 <= d3) return dot(bp, bp); // vertex b
    const double vc = d1 * d4 - d3 * d2;
    if (vc <= 0.0 && d1 >= 0.0 && d3 <= 0.0) { // edge ab
        const double t = d1 / (d1 - d3);
        const Vec3 e = p - (a + t * ab);
        return dot(e, e);
    }
    const Vec3 cp = p - c;
    const double d5 = dot(ab, cp), d6 = dot(ac, cp);
    if (d6 >= 0.0 && d5 <= d6) return dot(cp, cp); // vertex c
    const double vb = d5 * d2 - d1 * d6;
    if (vb <= 0.0 && d2 >= 0.0 && d6 <= 0.0) { // edge ac
        const double t = d2 / (d2 - d6);
        const Vec3 e = p - (a + t * ac);
        return dot(e, e);
    }
    const double va = d3 * d6 - d5 * d4;
    if (va <= 0.0 && (d4 - d3) >= 0.0 && (d5 - d6) >= 0.0) { // edge bc
        const double t = (d4 - d3) / ((d4 - d3) + (d5 - d6));
        const Vec3 e = p - (b + t * (c - b));
        return dot(e, e);
    }
    const double denom = va + vb + vc; // inside the face
    if (denom <= 0.0) { // degenerate triangle: fall back to its edges
        double best = dot(ap, ap);
        const Vec3 ends[3][2] = {{a, b}, {b, c}, {c, a}};
        for (const auto &seg : ends) {
            const Vec3 d = seg[1] - seg[0];
            const double len2 = dot(d, d);
            const double t = len2 > 0.0 ? std::clamp(dot(p - seg[0], d) / len2, 0.0, 1.0) : 0.0;
            const Vec3 e = p - (seg[0] + t * d);
            best = std::min(best, dot(e, e));
        }
        return best;
    }
    const double v = vb / denom, w = vc / denom;
    const Vec3 e = p - (a + v * ab + w * ac);
    return dot(e, e);
}

// A binary BVH over the triangles (median split on the longest axis of the centroids, leaves of
// at most four triangles), answering "distance from p to the nearest point of the surface".
class SurfaceDistance {
public:
    // Copies the triangles' corners (in BVH order): the mesh need not outlive this object.
    explicit SurfaceDistance(const Mesh &mesh) {
        if (mesh.triangles.empty()) throw std::invalid_argument("SurfaceDistance: empty mesh");
        std::vector<std::uint32_t> order(mesh.triangles.size());
        std::iota(order.begin(), order.end(), 0u);
        std::vector<Vec3> centroids(mesh.triangles.size());
        for (std::size_t i = 0; i < mesh.triangles.size(); ++i) {
            const Tri &f = mesh.triangles[i];
            centroids[i] = (1.0 / 3.0) * (mesh.vertices[f[0]] + mesh.vertices[f[1]] + mesh.vertices[f[2]]);
        }
        nodes_.reserve(2 * mesh.triangles.size() / kLeaf + 2);
        nodes_.emplace_back();
        build(mesh, order, centroids, 0, 0, static_cast<std::uint32_t>(order.size()));
        corners_.reserve(order.size());
        for (std::uint32_t t : order) {
            const Tri &f = mesh.triangles[t];
            corners_.push_back({mesh.vertices[f[0]], mesh.vertices[f[1]], mesh.vertices[f[2]]});
        }
    }

    double distance(const Vec3 &p) const { return std::sqrt(squared_distance(p)); }

    double squared_distance(const Vec3 &p) const {
        double best = std::numeric_limits<double>::infinity();
        std::uint32_t stack[128];
        int top = 0;
        stack[top++] = 0;
        while (top > 0) {
            const Node &n = nodes_[stack[--top]];
            if (n.box.squared_distance(p) >= best) continue;
            if (n.count > 0) {
                for (std::uint32_t i = n.first; i < n.first + n.count; ++i) {
                    const auto &t = corners_[i];
                    best = std::min(best, point_triangle_squared_distance(p, t[0], t[1], t[2]));
                }
            } else {
                // Visit the nearer child first (pushed last).
                const std::uint32_t l = n.first, r = n.first + 1;
                const double dl = nodes_[l].box.squared_distance(p), dr = nodes_[r].box.squared_distance(p);
                if (dl < dr) {
                    stack[top++] = r;
                    stack[top++] = l;
                } else {
                    stack[top++] = l;
                    stack[top++] = r;
                }
            }
        }
        return best;
    }

private:
    static constexpr std::uint32_t kLeaf = 4;
    struct Node {
        Box box;
        std::uint32_t first = 0; // first triangle (leaf) or left child index (inner; right = +1)
        std::uint32_t count = 0; // triangles in a leaf, 0 for an inner node
    };

    // Fills node `index` (already allocated) with the triangles order[begin, end).
    void build(const Mesh &mesh, std::vector<std::uint32_t> &order, const std::vector<Vec3> &centroids,
               std::uint32_t index, std::uint32_t begin, std::uint32_t end) {
        Box box, cbox;
        for (std::uint32_t i = begin; i < end; ++i) {
            for (std::uint32_t v : mesh.triangles[order[i]]) box.add(mesh.vertices[v]);
            cbox.add(centroids[order[i]]);
        }
        nodes_[index].box = box;
        if (end - begin <= kLeaf) {
            nodes_[index].first = begin;
            nodes_[index].count = end - begin;
            return;
        }
        const Vec3 extent = cbox.hi - cbox.lo;
        const int axis = extent[0] >= extent[1] && extent[0] >= extent[2] ? 0 : (extent[1] >= extent[2] ? 1 : 2);
        const std::uint32_t mid = begin + (end - begin) / 2;
        std::nth_element(order.begin() + begin, order.begin() + mid, order.begin() + end,
                         [&](std::uint32_t x, std::uint32_t y) { return centroids[x][axis] < centroids[y][axis]; });
        // The two children sit next to each other, so one index finds both.
        const std::uint32_t left = static_cast<std::uint32_t>(nodes_.size());
        nodes_.emplace_back();
        nodes_.emplace_back();
        nodes_[index].first = left;
        nodes_[index].count = 0;
        build(mesh, order, centroids, left, begin, mid);
        build(mesh, order, centroids, left + 1, mid, end);
    }

    std::vector<std::array<Vec3, 3>> corners_; // triangle i of the leaves' ranges
    std::vector<Node> nodes_;
};

// ---------------------------------------------------------------------------------------------
// Distances between surfaces

// Summary of one-sided distances (from samples of one surface to the other surface).
struct OneSided {
    double mean = 0.0;
    double p95 = 0.0;
    double max = 0.0;
};

inline OneSided summarize(std::vector<double> d) {
    OneSided s;
    if (d.empty()) return s;
    s.mean = std::accumulate(d.begin(), d.end(), 0.0) / static_cast<double>(d.size());
    // Nearest-rank 95th percentile.
    const std::size_t k = static_cast<std::size_t>(std::ceil(0.95 * static_cast<double>(d.size()))) - 1;
    std::nth_element(d.begin(), d.begin() + k, d.end());
    s.p95 = d[k];
    s.max = *std::max_element(d.begin(), d.end());
    return s;
}

// Symmetric comparison of two surfaces A and B, each distance divided by `scale` (the bounding
// box diagonal of the input the surfaces were reconstructed from).
struct Symmetric {
    OneSided a_to_b, b_to_a;
    // Chamfer distance: the sum of the two one-sided mean distances, and their average.
    double chamfer_sum() const { return a_to_b.mean + b_to_a.mean; }
    double chamfer_avg() const { return 0.5 * chamfer_sum(); }
    // 95th-percentile Hausdorff distance: the larger of the two one-sided 95th percentiles
    // (robust to a few stray samples, unlike the maximum).
    double hausdorff95() const { return std::max(a_to_b.p95, b_to_a.p95); }
    double hausdorff() const { return std::max(a_to_b.max, b_to_a.max); }
};

// Distances from points to a surface given as a function, divided by scale.
inline OneSided one_sided(const std::vector<Vec3> &from, const std::function<double(const Vec3 &)> &to,
                          double scale) {
    std::vector<double> d(from.size());
    for (std::size_t i = 0; i < from.size(); ++i) d[i] = to(from[i]) / scale;
    return summarize(std::move(d));
}

inline OneSided one_sided(const std::vector<Vec3> &from, const SurfaceDistance &to, double scale) {
    return one_sided(from, [&](const Vec3 &p) { return to.distance(p); }, scale);
}

// A surface with its samples and BVH, ready to be compared with others.
struct Measured {
    std::vector<Vec3> samples;
    SurfaceDistance distance;
    Measured(const Mesh &mesh, std::size_t n, std::uint64_t seed)
        : samples(sample_surface(canonical(mesh), n, seed)), distance(mesh) {}
};

inline Symmetric compare(const Measured &a, const Measured &b, double scale) {
    return {one_sided(a.samples, b.distance, scale), one_sided(b.samples, a.distance, scale)};
}

} // namespace metrics
