//! Analytic shapes: point samplers with outward unit normals, noise, exact distances, and small
//! reference meshes.

use crate::point::{f32x3, v3};
use crate::Rng;
use glam::DVec3;
use std::f64::consts::{PI, TAU};

// ---------------------------------------------------------------------------------------------
// Point samplers for analytic shapes
// ---------------------------------------------------------------------------------------------

/// `n` points area-uniform on the sphere of `radius` about `center`, with outward unit normals.
/// Returns (positions, normals).
pub fn sample_sphere(
    n: usize,
    radius: f64,
    center: [f64; 3],
    seed: u64,
) -> (Vec<[f32; 3]>, Vec<[f32; 3]>) {
    assert!(radius > 0.0, "sphere radius must be positive");
    let mut rng = Rng::new(seed);
    let c = DVec3::from_array(center);
    let mut positions = Vec::with_capacity(n);
    let mut normals = Vec::with_capacity(n);
    for _ in 0..n {
        let d = DVec3::from_array(rng.unit_vector());
        positions.push(f32x3(c + radius * d));
        normals.push(f32x3(d));
    }
    (positions, normals)
}

/// `n` points area-uniform on the ring torus about the z axis with major radius `major_radius`
/// (centre of the tube) and minor radius `minor_radius` (tube radius), with outward unit normals.
///
/// Parametrisation p(u, v) = ((R + r cos v) cos u, (R + r cos v) sin u, r sin v); the area
/// element is r (R + r cos v) du dv, so (u, v) uniform is accepted with probability
/// (R + r cos v) / (R + r). Returns (positions, normals).
pub fn sample_torus(
    n: usize,
    major_radius: f64,
    minor_radius: f64,
    seed: u64,
) -> (Vec<[f32; 3]>, Vec<[f32; 3]>) {
    let (big, small) = (major_radius, minor_radius);
    assert!(
        small > 0.0 && big > small,
        "need a ring torus: major_radius > minor_radius > 0"
    );
    let mut rng = Rng::new(seed);
    let mut positions = Vec::with_capacity(n);
    let mut normals = Vec::with_capacity(n);
    while positions.len() < n {
        let u = rng.uniform(0.0, TAU);
        let v = rng.uniform(0.0, TAU);
        if rng.next_f64() * (big + small) >= big + small * v.cos() {
            continue;
        }
        let (su, cu) = u.sin_cos();
        let (sv, cv) = v.sin_cos();
        let normal = DVec3::new(cv * cu, cv * su, sv);
        positions.push(f32x3(DVec3::new(big * cu, big * su, 0.0) + small * normal));
        normals.push(f32x3(normal));
    }
    (positions, normals)
}

/// The sampling density of [`sample_sphere_nonuniform`] at height `z` (unit sphere), relative to
/// the density at the south pole z = −1: `ratio^((z + 1) / 2)`. It grows geometrically from 1 at
/// z = −1 to `ratio` at z = +1, so every band of equal height has the same density contrast.
pub fn nonuniform_sphere_density(z: f64, ratio: f64) -> f64 {
    ratio.powf((z + 1.0) / 2.0)
}

/// `n` points on the unit sphere about the origin whose area density varies `ratio`× from the
/// south pole (sparsest) to the north pole (densest), as [`nonuniform_sphere_density`], with
/// outward unit normals. Area-uniform directions are accepted with probability
/// density(z) / ratio. Returns (positions, normals).
pub fn sample_sphere_nonuniform(n: usize, seed: u64, ratio: f64) -> (Vec<[f32; 3]>, Vec<[f32; 3]>) {
    assert!(ratio >= 1.0, "ratio must be >= 1");
    let mut rng = Rng::new(seed);
    let mut positions = Vec::with_capacity(n);
    let mut normals = Vec::with_capacity(n);
    while positions.len() < n {
        let d = DVec3::from_array(rng.unit_vector());
        if rng.next_f64() * ratio >= nonuniform_sphere_density(d.z, ratio) {
            continue;
        }
        positions.push(f32x3(d));
        normals.push(f32x3(d));
    }
    (positions, normals)
}

/// `n` points area-uniform on the surface of the axis-aligned box with the given half extents
/// about the origin (sharp edges and corners), each with the outward normal of its face.
/// A thin plate is a box with one small half extent. Returns (positions, normals).
pub fn sample_box(n: usize, half_extents: [f64; 3], seed: u64) -> (Vec<[f32; 3]>, Vec<[f32; 3]>) {
    assert!(
        half_extents.iter().all(|&h| h > 0.0),
        "half extents must be positive"
    );
    let [hx, hy, hz] = half_extents;
    // Face pairs by normal axis, with their areas (each face of the pair has this area).
    let areas = [hy * hz, hx * hz, hx * hy];
    let total: f64 = areas.iter().sum();
    let mut rng = Rng::new(seed);
    let mut positions = Vec::with_capacity(n);
    let mut normals = Vec::with_capacity(n);
    for _ in 0..n {
        let pick = rng.next_f64() * total;
        let axis = if pick < areas[0] {
            0
        } else if pick < areas[0] + areas[1] {
            1
        } else {
            2
        };
        let side = if rng.next_f64() < 0.5 { -1.0 } else { 1.0 };
        let mut p = [0.0; 3];
        for (a, coordinate) in p.iter_mut().enumerate() {
            *coordinate = if a == axis {
                side * half_extents[a]
            } else {
                rng.uniform(-half_extents[a], half_extents[a])
            };
        }
        let mut normal = [0.0f32; 3];
        normal[axis] = side as f32;
        positions.push(f32x3(DVec3::from_array(p)));
        normals.push(normal);
    }
    (positions, normals)
}

/// `n` points on two copies of the torus of [`sample_torus`] (both about axes parallel to z,
/// in the plane z = 0), centred at x = ±(R + r + gap/2): their outer walls face each other
/// `gap` apart. Half the points on each, outward normals. Returns (positions, normals).
pub fn sample_two_tori(
    n: usize,
    major_radius: f64,
    minor_radius: f64,
    gap: f64,
    seed: u64,
) -> (Vec<[f32; 3]>, Vec<[f32; 3]>) {
    let offset = major_radius + minor_radius + 0.5 * gap;
    let (mut positions, mut normals) = sample_torus(n / 2, major_radius, minor_radius, seed);
    for p in positions.iter_mut() {
        p[0] = (p[0] as f64 - offset) as f32;
    }
    let (second, second_normals) =
        sample_torus(n - n / 2, major_radius, minor_radius, seed.wrapping_add(1));
    positions.extend(
        second
            .iter()
            .map(|p| [(p[0] as f64 + offset) as f32, p[1], p[2]]),
    );
    normals.extend(second_normals);
    (positions, normals)
}

/// `n` points on a hollow ball: the sphere of radius 1 about the origin (normals outward) and,
/// inside it, the sphere of radius 1 − `wall` (normals inward, towards the centre: the cavity's
/// wall), area-uniform over both, so the solid between them is `wall` thick. Returns
/// (positions, normals).
pub fn sample_hollow_ball(n: usize, wall: f64, seed: u64) -> (Vec<[f32; 3]>, Vec<[f32; 3]>) {
    assert!(
        wall > 0.0 && wall < 1.0,
        "the wall must be thinner than the ball"
    );
    let inner = 1.0 - wall;
    let outer_count = (n as f64 / (1.0 + inner * inner)).round() as usize;
    let (mut positions, mut normals) = sample_sphere(outer_count, 1.0, [0.0; 3], seed);
    let (p, m) = sample_sphere(n - outer_count, inner, [0.0; 3], seed.wrapping_add(1));
    positions.extend(p);
    normals.extend(m.iter().map(|v| v.map(|c| -c)));
    (positions, normals)
}

/// `n` points on two boxes with the given half extents, stacked along z with a `gap` between
/// them (the lower box's top face and the upper box's bottom face `gap` apart, facing each
/// other), half the points on each, outward normals. Returns (positions, normals).
pub fn sample_two_boxes(
    n: usize,
    half_extents: [f64; 3],
    gap: f64,
    seed: u64,
) -> (Vec<[f32; 3]>, Vec<[f32; 3]>) {
    let offset = half_extents[2] + 0.5 * gap;
    let (mut positions, mut normals) = sample_box(n / 2, half_extents, seed);
    for p in positions.iter_mut() {
        p[2] = (p[2] as f64 - offset) as f32;
    }
    let (upper, upper_normals) = sample_box(n - n / 2, half_extents, seed.wrapping_add(1));
    positions.extend(
        upper
            .iter()
            .map(|p| [p[0], p[1], (p[2] as f64 + offset) as f32]),
    );
    normals.extend(upper_normals);
    (positions, normals)
}

/// Thins a sampling unevenly: each point is kept with probability
/// ratio^((t − 1) / 2), t = the point's x mapped linearly from the points' x range onto
/// [−1, 1], so the density falls `ratio`× from the largest x to the smallest. Returns the kept
/// (positions, normals).
pub fn thin_unevenly(
    positions: &[[f32; 3]],
    normals: &[[f32; 3]],
    ratio: f64,
    seed: u64,
) -> (Vec<[f32; 3]>, Vec<[f32; 3]>) {
    assert!(ratio >= 1.0, "ratio must be >= 1");
    let (lo, hi) = positions
        .iter()
        .fold((f64::INFINITY, f64::NEG_INFINITY), |(lo, hi), p| {
            (lo.min(p[0] as f64), hi.max(p[0] as f64))
        });
    let mut rng = Rng::new(seed);
    let mut kept = (Vec::new(), Vec::new());
    for (p, n) in positions.iter().zip(normals) {
        let t = if hi > lo {
            2.0 * (p[0] as f64 - lo) / (hi - lo) - 1.0
        } else {
            1.0
        };
        if rng.next_f64() < ratio.powf((t - 1.0) / 2.0) {
            kept.0.push(*p);
            kept.1.push(*n);
        }
    }
    kept
}

/// A unit vector perpendicular to `n` (unit), in a uniformly random direction about it.
fn random_tangent(rng: &mut Rng, n: DVec3) -> DVec3 {
    loop {
        let g = DVec3::from_array(rng.unit_vector());
        let t = g - g.dot(n) * n;
        let len = t.length();
        if len > 1e-3 {
            return t / len;
        }
    }
}

/// Each normal rotated by exactly `angle` radians (as far as f32 allows) about a random axis
/// perpendicular to it, so the perturbed normal lies on the cone of half-angle `angle` about the
/// original, at a uniformly random azimuth. Input normals need not be unit; outputs are unit.
pub fn perturb_normals(normals: &[[f32; 3]], angle: f64, seed: u64) -> Vec<[f32; 3]> {
    let mut rng = Rng::new(seed);
    let (s, c) = angle.sin_cos();
    normals
        .iter()
        .map(|&n| {
            let n = v3(n).normalize();
            let t = random_tangent(&mut rng, n);
            f32x3(c * n + s * t)
        })
        .collect()
}

/// Each normal rotated about a random perpendicular axis by an angle θ = |N(0, σ²)| radians
/// (half-normal, capped at π), with σ = `sigma`: the mean angular error is σ·√(2/π) ≈ 0.80 σ and
/// the RMS angular error is σ. Outputs are unit.
pub fn perturb_normals_gaussian(normals: &[[f32; 3]], sigma: f64, seed: u64) -> Vec<[f32; 3]> {
    let mut rng = Rng::new(seed);
    normals
        .iter()
        .map(|&n| {
            let n = v3(n).normalize();
            let t = random_tangent(&mut rng, n);
            let theta = (sigma * rng.normal()).abs().min(PI);
            f32x3(theta.cos() * n + theta.sin() * t)
        })
        .collect()
}

/// Each position moved by an isotropic Gaussian offset with standard deviation `sigma` per axis.
pub fn jitter_positions(positions: &[[f32; 3]], sigma: f64, seed: u64) -> Vec<[f32; 3]> {
    let mut rng = Rng::new(seed);
    positions
        .iter()
        .map(|&p| {
            let offset = DVec3::new(rng.normal(), rng.normal(), rng.normal()) * sigma;
            f32x3(v3(p) + offset)
        })
        .collect()
}

/// The angle in radians between two (not necessarily unit) vectors.
pub fn angle_between(a: [f32; 3], b: [f32; 3]) -> f64 {
    let (a, b) = (v3(a), v3(b));
    // atan2 of |a×b| and a·b is accurate for small and large angles alike.
    a.cross(b).length().atan2(a.dot(b))
}

// ---------------------------------------------------------------------------------------------
// Exact distances to the analytic shapes
// ---------------------------------------------------------------------------------------------

/// Unsigned distance to the sphere of `radius` about `center`: | |p − c| − r |.
pub fn sphere_distance(
    center: [f64; 3],
    radius: f64,
) -> impl Fn([f64; 3]) -> f64 + Sync + Send + Copy {
    let c = DVec3::from_array(center);
    move |p| ((DVec3::from_array(p) - c).length() - radius).abs()
}

/// Signed distance to the torus of [`sample_torus`] (positive outside):
/// √((ρ − R)² + z²) − r with ρ = √(x² + y²). Exact everywhere (on the z axis every point of the
/// core circle is equally near, and the formula still holds).
pub fn torus_signed_distance(
    major_radius: f64,
    minor_radius: f64,
) -> impl Fn([f64; 3]) -> f64 + Sync + Send + Copy {
    move |p| {
        let rho = (p[0] * p[0] + p[1] * p[1]).sqrt();
        (rho - major_radius).hypot(p[2]) - minor_radius
    }
}

/// Unsigned distance to the torus of [`sample_torus`]: |[`torus_signed_distance`]|.
pub fn torus_distance(
    major_radius: f64,
    minor_radius: f64,
) -> impl Fn([f64; 3]) -> f64 + Sync + Send + Copy {
    let signed = torus_signed_distance(major_radius, minor_radius);
    move |p| signed(p).abs()
}

/// Diagonal of the bounding box of a sphere: 2√3 r.
pub fn sphere_bbox_diagonal(radius: f64) -> f64 {
    2.0 * 3f64.sqrt() * radius
}

/// Diagonal of the bounding box of the torus of [`sample_torus`]:
/// box [−(R+r), R+r]² × [−r, r], diagonal √(8 (R+r)² + 4 r²).
pub fn torus_bbox_diagonal(major_radius: f64, minor_radius: f64) -> f64 {
    let outer = major_radius + minor_radius;
    (8.0 * outer * outer + 4.0 * minor_radius * minor_radius).sqrt()
}

// ---------------------------------------------------------------------------------------------
// Small reference meshes
// ---------------------------------------------------------------------------------------------

/// Flips triangles whose normal points against `outward(centroid)`.
fn orient_outward(
    positions: &[[f32; 3]],
    triangles: &mut [[u32; 3]],
    outward: impl Fn(DVec3) -> DVec3,
) {
    for t in triangles.iter_mut() {
        let [a, b, c] = t.map(|k| v3(positions[k as usize]));
        if (b - a).cross(c - a).dot(outward((a + b + c) / 3.0)) < 0.0 {
            t.swap(1, 2);
        }
    }
}

/// The regular octahedron with vertices ±e_x, ±e_y, ±e_z (on the unit sphere), 8 outward
/// counter-clockwise triangles.
pub fn octahedron() -> (Vec<[f32; 3]>, Vec<[u32; 3]>) {
    let positions = vec![
        [1.0, 0.0, 0.0],
        [-1.0, 0.0, 0.0],
        [0.0, 1.0, 0.0],
        [0.0, -1.0, 0.0],
        [0.0, 0.0, 1.0],
        [0.0, 0.0, -1.0],
    ];
    let mut triangles = Vec::new();
    for x in [0, 1] {
        for y in [2, 3] {
            for z in [4, 5] {
                triangles.push([x, y, z]);
            }
        }
    }
    orient_outward(&positions, &mut triangles, |c| c);
    (positions, triangles)
}

/// An icosahedron subdivided `subdivisions` times (each triangle into 4, new vertices pushed
/// onto the unit sphere): 20·4^k outward triangles, vertices on the unit sphere.
pub fn icosphere(subdivisions: u32) -> (Vec<[f32; 3]>, Vec<[u32; 3]>) {
    let phi = (1.0 + 5f64.sqrt()) / 2.0;
    let mut verts: Vec<DVec3> = Vec::new();
    for s1 in [-1.0, 1.0] {
        for s2 in [-phi, phi] {
            verts.push(DVec3::new(s1, s2, 0.0));
            verts.push(DVec3::new(0.0, s1, s2));
            verts.push(DVec3::new(s2, 0.0, s1));
        }
    }
    // The faces are the triples of mutually adjacent vertices (edge length 2).
    let adjacent = |i: usize, j: usize| ((verts[i] - verts[j]).length() - 2.0).abs() < 1e-9;
    let mut faces: Vec<[u32; 3]> = Vec::new();
    for i in 0..12 {
        for j in i + 1..12 {
            for k in j + 1..12 {
                if adjacent(i, j) && adjacent(j, k) && adjacent(i, k) {
                    faces.push([i as u32, j as u32, k as u32]);
                }
            }
        }
    }
    let mut verts: Vec<DVec3> = verts.into_iter().map(|v| v.normalize()).collect();
    for _ in 0..subdivisions {
        let mut midpoint = std::collections::HashMap::new();
        let mut next = Vec::with_capacity(faces.len() * 4);
        let mut mid = |a: u32, b: u32, verts: &mut Vec<DVec3>| -> u32 {
            *midpoint.entry((a.min(b), a.max(b))).or_insert_with(|| {
                verts.push(((verts[a as usize] + verts[b as usize]) * 0.5).normalize());
                (verts.len() - 1) as u32
            })
        };
        for [a, b, c] in faces {
            let ab = mid(a, b, &mut verts);
            let bc = mid(b, c, &mut verts);
            let ca = mid(c, a, &mut verts);
            next.extend([[a, ab, ca], [ab, b, bc], [ca, bc, c], [ab, bc, ca]]);
        }
        faces = next;
    }
    let positions: Vec<[f32; 3]> = verts.into_iter().map(f32x3).collect();
    orient_outward(&positions, &mut faces, |c| c);
    (positions, faces)
}

/// A torus about the z axis (major radius R, minor r) as an `nu` × `nv` grid of quads split
/// into outward triangles, vertices on the true torus. Closed, genus 1 (χ = 0).
pub fn torus_mesh(
    major_radius: f64,
    minor_radius: f64,
    nu: usize,
    nv: usize,
) -> (Vec<[f32; 3]>, Vec<[u32; 3]>) {
    assert!(nu >= 3 && nv >= 3);
    let mut positions = Vec::with_capacity(nu * nv);
    for i in 0..nu {
        let (su, cu) = (TAU * i as f64 / nu as f64).sin_cos();
        for j in 0..nv {
            let (sv, cv) = (TAU * j as f64 / nv as f64).sin_cos();
            let ring = major_radius + minor_radius * cv;
            positions.push(f32x3(DVec3::new(ring * cu, ring * su, minor_radius * sv)));
        }
    }
    let id = |i: usize, j: usize| ((i % nu) * nv + j % nv) as u32;
    let mut triangles = Vec::with_capacity(2 * nu * nv);
    for i in 0..nu {
        for j in 0..nv {
            let (a, b, c, d) = (id(i, j), id(i + 1, j), id(i + 1, j + 1), id(i, j + 1));
            triangles.push([a, b, c]);
            triangles.push([a, c, d]);
        }
    }
    orient_outward(&positions, &mut triangles, |p| {
        let axis = DVec3::new(p.x, p.y, 0.0).normalize() * major_radius;
        p - axis
    });
    (positions, triangles)
}
