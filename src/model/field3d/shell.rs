//! A synthetic hair-like volume (a thick shell with constraints) for tests and benchmarks.

use crate::base::grid::Grid;

/// A test problem: grid, hair mask and constraints.
pub struct TestVolume {
    pub grid: Grid,
    pub h: Vec<u32>,
    pub constraints: Vec<(u32, [f32; 3])>,
}

/// A hair-like volume in an `n³` grid: the shell between two ellipsoids around a head
/// (centre slightly above the grid centre in image rows), with the face (lower front) and
/// everything below the neck cut away. Constraints as C13 §3 builds them: on the front
/// boundary (the H cell nearest the camera in each column) the tangent of a smooth, mostly
/// downward-flowing field projected onto the outer surface, and on every third cell touching
/// the inner (scalp) ellipsoid its outward normal.
pub fn test_shell(n: u32) -> TestVolume {
    let nf = n as f32;
    let c = [0.5 * nf, 0.45 * nf, 0.5 * nf];
    let ro = [0.44 * nf, 0.42 * nf, 0.42 * nf];
    let ri = [0.28 * nf, 0.29 * nf, 0.27 * nf];
    let grid = Grid {
        dims: [n; 3],
        origin: [0.0; 3],
        cell: 1.0,
    };
    let ell =
        |p: [f32; 3], r: [f32; 3]| -> f32 { (0..3).map(|a| ((p[a] - c[a]) / r[a]).powi(2)).sum() };
    let centre = |x: u32, y: u32, z: u32| [x as f32 + 0.5, y as f32 + 0.5, z as f32 + 0.5];
    let in_h = |p: [f32; 3]| -> bool {
        let (dy, dz) = (p[1] - c[1], p[2] - c[2]);
        let face = dz > 0.12 * nf && dy > -0.08 * nf;
        let below = dy > 0.3 * nf;
        ell(p, ro) <= 1.0 && ell(p, ri) > 1.0 && !face && !below
    };
    let mut h = vec![0u32; grid.len()];
    for z in 0..n {
        for y in 0..n {
            for x in 0..n {
                h[grid.index(x, y, z)] = in_h(centre(x, y, z)) as u32;
            }
        }
    }
    let normalise = |v: [f32; 3]| {
        let l = (v[0] * v[0] + v[1] * v[1] + v[2] * v[2]).sqrt();
        [v[0] / l, v[1] / l, v[2] / l]
    };
    let grad = |p: [f32; 3], r: [f32; 3]| {
        normalise([
            (p[0] - c[0]) / (r[0] * r[0]),
            (p[1] - c[1]) / (r[1] * r[1]),
            (p[2] - c[2]) / (r[2] * r[2]),
        ])
    };
    let mut constraints = Vec::new();
    // Front boundary: largest depth (z) in each (x, y) column.
    for y in 0..n {
        for x in 0..n {
            let Some(z) = (0..n).rev().find(|&z| h[grid.index(x, y, z)] != 0) else {
                continue;
            };
            let p = centre(x, y, z);
            let q = [(p[0] - c[0]) / nf, (p[1] - c[1]) / nf];
            // Downward flow (+y is down in volume space) with a gentle parting swirl.
            let t0 = [2.0 * q[0] + 0.3 * (6.0 * q[1]).sin(), 1.0, 0.4 * q[1]];
            let nrm = grad(p, ro);
            let d = t0[0] * nrm[0] + t0[1] * nrm[1] + t0[2] * nrm[2];
            let t = [t0[0] - d * nrm[0], t0[1] - d * nrm[1], t0[2] - d * nrm[2]];
            constraints.push((grid.index(x, y, z) as u32, normalise(t)));
        }
    }
    // Scalp normals: cells with a 6-neighbour inside the inner ellipsoid.
    for z in 1..n - 1 {
        for y in 1..n - 1 {
            for x in 1..n - 1 {
                let i = grid.index(x, y, z);
                if h[i] == 0 || (x + y + z) % 3 != 0 {
                    continue;
                }
                let touches = [
                    (x - 1, y, z),
                    (x + 1, y, z),
                    (x, y - 1, z),
                    (x, y + 1, z),
                    (x, y, z - 1),
                    (x, y, z + 1),
                ]
                .iter()
                .any(|&(a, b, d)| ell(centre(a, b, d), ri) <= 1.0);
                if touches {
                    constraints.push((i as u32, grad(centre(x, y, z), ri)));
                }
            }
        }
    }
    TestVolume {
        grid,
        h,
        constraints,
    }
}
