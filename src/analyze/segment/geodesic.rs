//! Geodesic distance from the strokes, a data term that uses where the user drew and not
//! only what colours they drew on (issue 19; geodesic segmentation as in Bai and Sapiro 2007
//! and Criminisi et al.'s GeoS 2008).
//!
//! A face, a chest or a shop window of nearly the hair's colour still meets the hair at an
//! edge: from a background stroke on it, every pixel of that smooth region is reached
//! without crossing one, while a path from a hair stroke must cross it. A path's cost is
//! its length plus `GAMMA` times the colour change along it, on a slightly blurred image so
//! that strand texture inside the hair does not count as an edge. Distances are found by
//! alternating forward and backward raster sweeps over the 8-neighbourhood (a few sweeps
//! reach the exact Dijkstra result on all but contrived mazes).

/// Weight of colour change (8-bit levels, Euclidean in RGB) against length (px).
const GAMMA: f32 = 1.0;
/// Forward + backward sweep pairs.
const SWEEPS: usize = 3;

/// Geodesic distance of every pixel to the nearest pixel with `seed[i]`.
pub(super) fn geodesic(rgb: &[[f32; 3]], w: usize, h: usize, seed: &[bool]) -> Vec<f32> {
    let img = blur(rgb, w, h);
    let mut d: Vec<f32> = seed
        .iter()
        .map(|&s| if s { 0.0 } else { f32::INFINITY })
        .collect();
    let step = |a: usize, b: usize, len: f32| -> f32 {
        let (p, q) = (img[a], img[b]);
        let c = ((p[0] - q[0]).powi(2) + (p[1] - q[1]).powi(2) + (p[2] - q[2]).powi(2)).sqrt();
        len + GAMMA * c
    };
    let d2 = std::f32::consts::SQRT_2;
    // Neighbours already visited in a forward sweep: (dx, dy, length).
    let back: [(isize, isize, f32); 4] = [(-1, 0, 1.0), (-1, -1, d2), (0, -1, 1.0), (1, -1, d2)];
    for _ in 0..SWEEPS {
        for forward in [true, false] {
            for k in 0..w * h {
                let i = if forward { k } else { w * h - 1 - k };
                let (x, y) = ((i % w) as isize, (i / w) as isize);
                let mut best = d[i];
                for &(dx, dy, len) in &back {
                    let (dx, dy) = if forward { (dx, dy) } else { (-dx, -dy) };
                    let (nx, ny) = (x + dx, y + dy);
                    if nx < 0 || ny < 0 || nx >= w as isize || ny >= h as isize {
                        continue;
                    }
                    let j = ny as usize * w + nx as usize;
                    if d[j].is_finite() {
                        best = best.min(d[j] + step(i, j, len));
                    }
                }
                d[i] = best;
            }
        }
    }
    d
}

/// 5x5 box blur (separable, clamped at the border).
fn blur(rgb: &[[f32; 3]], w: usize, h: usize) -> Vec<[f32; 3]> {
    let r = 2usize;
    let pass = |src: &[[f32; 3]], horizontal: bool| -> Vec<[f32; 3]> {
        let mut out = vec![[0f32; 3]; src.len()];
        for y in 0..h {
            for x in 0..w {
                let (c, n) = if horizontal { (x, w) } else { (y, h) };
                let (a, b) = (c.saturating_sub(r), (c + r).min(n - 1));
                let mut s = [0f32; 3];
                for k in a..=b {
                    let j = if horizontal { y * w + k } else { k * w + x };
                    for (sc, v) in s.iter_mut().zip(src[j]) {
                        *sc += v;
                    }
                }
                let m = (b - a + 1) as f32;
                out[y * w + x] = [s[0] / m, s[1] / m, s[2] / m];
            }
        }
        out
    };
    pass(&pass(rgb, true), false)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn an_edge_costs_more_than_distance() {
        // Left third dark, the rest light; seed at the far right. The pixel just across the
        // edge is nearer in pixels than the dark region's far end is from the edge, yet the
        // dark side is far in geodesic terms.
        let (w, h) = (30, 5);
        let rgb: Vec<[f32; 3]> = (0..w * h)
            .map(|i| if i % w < 10 { [20.0; 3] } else { [200.0; 3] })
            .collect();
        let seed: Vec<bool> = (0..w * h).map(|i| i % w == w - 1).collect();
        let d = geodesic(&rgb, w, h, &seed);
        let (light, dark) = (d[2 * w + 12], d[2 * w + 7]);
        println!("light side {light:.1}, dark side {dark:.1}");
        assert!((light - 17.0).abs() < 1.0, "{light}");
        assert!(dark > light + 100.0, "{dark} vs {light}");
    }
}
