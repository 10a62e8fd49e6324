//! What every mesh psr returns must be, whatever the input.
//!
//! Closed where it can be: the extraction closes the surface by construction, except where the
//! level set reaches the bounding cube (a plane, a line, an open scan under Neumann conditions:
//! the Poisson solution's isosurface is cut off by the cube, as PoissonRecon's is), so an open
//! edge is allowed on the cube's faces only.

use std::collections::HashMap;

/// Panics unless the triangles index `vertex_count` vertices, no triangle repeats a corner,
/// and no edge is used twice in one direction (an edge of three or more triangles, or two
/// triangles of opposite orientation); returns the boundary edges (those used in one direction
/// only), for the caller to check where they lie.
pub fn assert_oriented_manifold(
    vertex_count: usize,
    triangles: &[[u32; 3]],
    what: &str,
) -> Vec<(u32, u32)> {
    let mut directed: HashMap<(u32, u32), u32> = HashMap::with_capacity(triangles.len() * 3);
    for (t, tri) in triangles.iter().enumerate() {
        for &v in tri {
            assert!(
                (v as usize) < vertex_count,
                "{what}: triangle {t} indexes vertex {v} of {vertex_count}"
            );
        }
        assert!(
            tri[0] != tri[1] && tri[1] != tri[2] && tri[0] != tri[2],
            "{what}: triangle {t} {tri:?} repeats a corner"
        );
        for k in 0..3 {
            *directed.entry((tri[k], tri[(k + 1) % 3])).or_default() += 1;
        }
    }
    let mut boundary = Vec::new();
    for (&(a, b), &uses) in &directed {
        assert_eq!(
            uses, 1,
            "{what}: edge {a}->{b} is used {uses} times in one direction"
        );
        if !directed.contains_key(&(b, a)) {
            boundary.push((a, b));
        }
    }
    boundary
}

/// Panics unless every coordinate is finite.
pub fn assert_finite(values: &[f32], what: &str) {
    if let Some(i) = values.iter().position(|v| !v.is_finite()) {
        panic!("{what}: value {i} is {}", values[i]);
    }
}
