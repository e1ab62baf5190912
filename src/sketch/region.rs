//! The hair region a sketch covers, stored with it so that synthesis needs nothing but the
//! sketch: the mask's outline as closed polygons on the pixel-corner lattice, filled by the
//! even-odd rule (holes are polygons inside polygons). CZ06 draws the region's edge with
//! boundary primitives (a, b), but a pursuit's curves rarely close a loop, so the outline is
//! kept as its own small part of the file; an empty outline means the whole image (a crop
//! of hair or fur).
//!
//! Tracing, simplifying and filling a few hundred vertices: sequential, CPU.

use super::Region;

/// Settings of the outline.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct OutlineParams {
    /// Douglas-Peucker tolerance, px: a vertex is dropped when the simplified outline stays
    /// within this distance of it.
    pub tolerance: f32,
    /// Loops enclosing fewer pixels than this are dropped (specks of mask).
    pub min_area: f32,
}

impl Default for OutlineParams {
    fn default() -> Self {
        OutlineParams {
            tolerance: 1.5,
            min_area: 16.0,
        }
    }
}

/// The outline of `hair` (W*H, row-major): empty when every pixel is hair.
pub fn outline(hair: &[bool], w: u32, h: u32, p: &OutlineParams) -> Region {
    let (wu, hu) = (w as usize, h as usize);
    assert_eq!(hair.len(), wu * hu, "mask size");
    if hair.iter().all(|&m| m) {
        return Vec::new();
    }
    let at = |x: i64, y: i64| -> bool {
        x >= 0 && y >= 0 && x < w as i64 && y < h as i64 && hair[y as usize * wu + x as usize]
    };
    // Directed edges of pixel sides between hair and non-hair, hair on the left (y down:
    // the left of a move (dx, dy) is (dy, −dx)). Keyed by their start corner.
    let cw = wu + 1;
    let corner = |x: i64, y: i64| y as usize * cw + x as usize;
    let mut out_edges: Vec<[u32; 2]> = vec![[u32::MAX; 2]; cw * (hu + 1)];
    let mut push = |from: usize, to: usize| {
        let e = &mut out_edges[from];
        if e[0] == u32::MAX {
            e[0] = to as u32;
        } else {
            e[1] = to as u32;
        }
    };
    for y in 0..=h as i64 {
        for x in 0..=w as i64 {
            // Horizontal side between (x, y−1) above and (x, y) below, from corner (x, y)
            // to (x+1, y).
            if x < w as i64 {
                let (up, down) = (at(x, y - 1), at(x, y));
                if up && !down {
                    // Moving +x, the left is −y (up): hair above.
                    push(corner(x, y), corner(x + 1, y));
                } else if down && !up {
                    push(corner(x + 1, y), corner(x, y));
                }
            }
            // Vertical side between (x−1, y) left and (x, y) right, corner (x, y) to (x, y+1).
            if y < h as i64 {
                let (left, right) = (at(x - 1, y), at(x, y));
                if right && !left {
                    // Moving +y, the left is +x: hair to the right.
                    push(corner(x, y), corner(x, y + 1));
                } else if left && !right {
                    push(corner(x, y + 1), corner(x, y));
                }
            }
        }
    }
    let xy = |c: usize| [(c % cw) as i64, (c / cw) as i64];
    let mut loops = Vec::new();
    for start in 0..out_edges.len() {
        while out_edges[start][0] != u32::MAX {
            let mut pts = vec![xy(start)];
            let mut cur = start;
            let mut prev_dir = [0i64, 0];
            loop {
                let e = out_edges[cur];
                // At a corner with two ways out (pixels touching diagonally), turn left, so
                // that diagonal neighbours stay apart: loops never cross.
                let pick = if e[1] != u32::MAX {
                    let d0 = dir(xy(cur), xy(e[0] as usize));
                    let left = [prev_dir[1], -prev_dir[0]];
                    if d0 == left {
                        0
                    } else {
                        1
                    }
                } else {
                    0
                };
                let next = e[pick] as usize;
                let slot = &mut out_edges[cur];
                if pick == 0 {
                    slot[0] = slot[1];
                }
                slot[1] = u32::MAX;
                prev_dir = dir(xy(cur), xy(next));
                cur = next;
                if cur == start {
                    break;
                }
                pts.push(xy(cur));
            }
            loops.push(pts);
        }
    }
    loops
        .into_iter()
        .filter(|l| area(l).abs() >= p.min_area as f64)
        .map(|l| {
            simplify_closed(&corners_only(&l), p.tolerance as f64)
                .into_iter()
                .map(|q| [q[0] as u32, q[1] as u32])
                .collect::<Vec<_>>()
        })
        .filter(|l| l.len() >= 3)
        .collect()
}

fn dir(a: [i64; 2], b: [i64; 2]) -> [i64; 2] {
    [b[0] - a[0], b[1] - a[1]]
}

/// Signed area (shoelace); positive for loops with hair on their left (y down).
fn area(l: &[[i64; 2]]) -> f64 {
    let n = l.len();
    let mut s = 0i64;
    for i in 0..n {
        let (a, b) = (l[i], l[(i + 1) % n]);
        s += a[0] * b[1] - b[0] * a[1];
    }
    -0.5 * s as f64
}

/// Drops the collinear corners of a staircase loop.
fn corners_only(l: &[[i64; 2]]) -> Vec<[i64; 2]> {
    let n = l.len();
    (0..n)
        .filter(|&i| {
            let (a, b, c) = (l[(i + n - 1) % n], l[i], l[(i + 1) % n]);
            dir(a, b) != dir(b, c)
        })
        .map(|i| l[i])
        .collect()
}

/// Douglas-Peucker on a closed loop: split at the vertex farthest from the first, simplify
/// both halves as open chains.
fn simplify_closed(l: &[[i64; 2]], tol: f64) -> Vec<[i64; 2]> {
    let n = l.len();
    if n <= 3 {
        return l.to_vec();
    }
    let d2 = |a: [i64; 2], b: [i64; 2]| ((a[0] - b[0]).pow(2) + (a[1] - b[1]).pow(2)) as f64;
    let far = (1..n)
        .max_by(|&i, &j| d2(l[0], l[i]).total_cmp(&d2(l[0], l[j])).then(j.cmp(&i)))
        .expect("n > 3");
    let mut keep = vec![false; n + 1];
    keep[0] = true;
    keep[far] = true;
    keep[n] = true;
    let ring: Vec<[i64; 2]> = l.iter().copied().chain(std::iter::once(l[0])).collect();
    dp(&ring, 0, far, tol, &mut keep);
    dp(&ring, far, n, tol, &mut keep);
    (0..n).filter(|&i| keep[i]).map(|i| l[i]).collect()
}

fn dp(p: &[[i64; 2]], a: usize, b: usize, tol: f64, keep: &mut [bool]) {
    if b <= a + 1 {
        return;
    }
    let (pa, pb) = (p[a], p[b]);
    let (dx, dy) = ((pb[0] - pa[0]) as f64, (pb[1] - pa[1]) as f64);
    let len = dx.hypot(dy);
    let mut best = (0.0, a);
    for (i, q) in p.iter().enumerate().take(b).skip(a + 1) {
        let (qx, qy) = ((q[0] - pa[0]) as f64, (q[1] - pa[1]) as f64);
        let d = if len > 0.0 {
            (qx * dy - qy * dx).abs() / len
        } else {
            qx.hypot(qy)
        };
        if d > best.0 {
            best = (d, i);
        }
    }
    if best.0 > tol {
        keep[best.1] = true;
        dp(p, a, best.1, tol, keep);
        dp(p, best.1, b, tol, keep);
    }
}

/// The pixels inside `region` (pixel centres, even-odd rule); every pixel when it is empty.
pub fn fill(region: &Region, w: u32, h: u32) -> Vec<bool> {
    let (wu, hu) = (w as usize, h as usize);
    if region.is_empty() {
        return vec![true; wu * hu];
    }
    let mut out = vec![false; wu * hu];
    let mut xs: Vec<f64> = Vec::new();
    for j in 0..hu {
        let yc = j as f64 + 0.5;
        xs.clear();
        for poly in region {
            let n = poly.len();
            for i in 0..n {
                let (a, b) = (poly[i], poly[(i + 1) % n]);
                let (ay, by) = (a[1] as f64, b[1] as f64);
                // Half-open in y, so a vertex on the scanline counts once.
                if (ay <= yc) != (by <= yc) {
                    let t = (yc - ay) / (by - ay);
                    xs.push(a[0] as f64 + t * (b[0] as f64 - a[0] as f64));
                }
            }
        }
        xs.sort_by(f64::total_cmp);
        for pair in xs.chunks_exact(2) {
            // Pixel centres i + 0.5 in [x0, x1).
            let i0 = (pair[0] - 0.5).ceil().max(0.0) as usize;
            let i1 = ((pair[1] - 0.5).ceil().max(0.0) as usize).min(wu);
            out[j * wu + i0.min(wu)..j * wu + i1].fill(true);
        }
    }
    out
}

/// Intersection over union of two masks (1 when both are empty).
pub fn iou(a: &[bool], b: &[bool]) -> f64 {
    let (mut i, mut u) = (0usize, 0usize);
    for (&x, &y) in a.iter().zip(b) {
        i += (x && y) as usize;
        u += (x || y) as usize;
    }
    if u == 0 {
        1.0
    } else {
        i as f64 / u as f64
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn disc(w: u32, h: u32, cx: f32, cy: f32, r: f32) -> Vec<bool> {
        (0..w * h)
            .map(|k| {
                let (x, y) = ((k % w) as f32 + 0.5, (k / w) as f32 + 0.5);
                (x - cx).hypot(y - cy) <= r
            })
            .collect()
    }

    #[test]
    fn a_rectangle_is_four_corners_and_fills_back_exactly() {
        let (w, h) = (20u32, 12u32);
        let m: Vec<bool> = (0..w * h)
            .map(|k| (3..15).contains(&(k % w)) && (2..9).contains(&(k / w)))
            .collect();
        let r = outline(&m, w, h, &OutlineParams::default());
        assert_eq!(r.len(), 1);
        assert_eq!(r[0].len(), 4, "{:?}", r[0]);
        assert_eq!(fill(&r, w, h), m);
    }

    #[test]
    fn a_ring_keeps_its_hole_and_a_speck_is_dropped() {
        let (w, h) = (64u32, 64u32);
        let outer = disc(w, h, 32.0, 32.0, 24.0);
        let inner = disc(w, h, 32.0, 32.0, 10.0);
        let mut m: Vec<bool> = outer.iter().zip(&inner).map(|(&o, &i)| o && !i).collect();
        m[0] = true; // one-pixel speck, below min_area
        let r = outline(&m, w, h, &OutlineParams::default());
        assert_eq!(r.len(), 2, "outer loop and hole");
        let back = fill(&r, w, h);
        let mut truth = m.clone();
        truth[0] = false;
        let j = iou(&back, &truth);
        println!(
            "ring: {} vertices, IoU {j:.4}",
            r.iter().map(|l| l.len()).sum::<usize>()
        );
        assert!(j > 0.95, "IoU {j}");
        assert!(!back[32 * 64 + 32], "the hole stays empty");
    }

    #[test]
    fn diagonal_touching_pixels_and_edges_of_the_image() {
        // A checkerboard 2x2 block touching diagonally, and a mask touching the borders.
        let (w, h) = (8u32, 8u32);
        let mut m = vec![false; 64];
        for &(x, y) in &[(2, 2), (3, 3)] {
            m[y * 8 + x] = true;
        }
        let r = outline(
            &m,
            w,
            h,
            &OutlineParams {
                tolerance: 0.0,
                min_area: 0.0,
            },
        );
        assert_eq!(r.len(), 2, "two single pixels stay two loops: {r:?}");
        assert_eq!(fill(&r, w, h), m);
        let full_row: Vec<bool> = (0..64).map(|k| k / 8 < 3).collect();
        let r = outline(&full_row, w, h, &OutlineParams::default());
        assert_eq!(fill(&r, w, h), full_row);
        assert!(outline(&[true; 64], 8, 8, &OutlineParams::default()).is_empty());
        assert!(fill(&Vec::new(), 8, 8).iter().all(|&v| v));
    }

    #[test]
    fn iou_tells_different_masks_apart() {
        let a = disc(40, 40, 20.0, 20.0, 10.0);
        let b = disc(40, 40, 26.0, 20.0, 10.0);
        assert_eq!(iou(&a, &a), 1.0);
        assert!(iou(&a, &b) < 0.7);
    }
}
