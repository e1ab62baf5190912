//! Binary mask morphology (disc and square dilation / erosion) and connected components.

use rayon::prelude::*;

/// The 8-neighbourhood as (dx, dy), row by row; `NEIGHBOURS_8[7 - d]` is the opposite of
/// `NEIGHBOURS_8[d]`.
pub const NEIGHBOURS_8: [(i32, i32); 8] = [
    (-1, -1),
    (0, -1),
    (1, -1),
    (-1, 0),
    (1, 0),
    (-1, 1),
    (0, 1),
    (1, 1),
];

/// Offsets (dx, dy) with dx² + dy² ≤ r² (`strict`: < r²): a disc structuring element.
pub fn disc(r: f32, strict: bool) -> Vec<(i64, i64)> {
    let ri = r.ceil() as i64;
    (-ri..=ri)
        .flat_map(|dy| (-ri..=ri).map(move |dx| (dx, dy)))
        .filter(|&(dx, dy)| {
            let d2 = (dx * dx + dy * dy) as f32;
            if strict {
                d2 < r * r
            } else {
                d2 <= r * r
            }
        })
        .collect()
}

/// Disc-style morphology with the structuring element `offs`: dilation sets a pixel where any
/// offset pixel is set, erosion where the pixel itself and every offset pixel are; off the
/// image reads as `outside`.
fn morph(
    m: &[bool],
    w: usize,
    h: usize,
    offs: &[(i64, i64)],
    outside: bool,
    erode: bool,
) -> Vec<bool> {
    let at = |x: i64, y: i64| {
        if x < 0 || y < 0 || x >= w as i64 || y >= h as i64 {
            outside
        } else {
            m[y as usize * w + x as usize]
        }
    };
    let mut out = vec![false; w * h];
    out.par_chunks_mut(w.max(1))
        .enumerate()
        .for_each(|(y, row)| {
            let y = y as i64;
            for (x, o) in row.iter_mut().enumerate() {
                let x = x as i64;
                *o = if erode {
                    at(x, y) && offs.iter().all(|&(dx, dy)| at(x + dx, y + dy))
                } else {
                    offs.iter().any(|&(dx, dy)| at(x + dx, y + dy))
                };
            }
        });
    out
}

/// Set where any pixel at one of `offs` from it is set; off the image counts as `outside`.
pub fn dilate_by(m: &[bool], w: usize, h: usize, offs: &[(i64, i64)], outside: bool) -> Vec<bool> {
    morph(m, w, h, offs, outside, false)
}

/// Set where the pixel itself and every pixel at one of `offs` from it are set; off the image
/// counts as `outside`.
pub fn erode_by(m: &[bool], w: usize, h: usize, offs: &[(i64, i64)], outside: bool) -> Vec<bool> {
    morph(m, w, h, offs, outside, true)
}

/// One pass of a square morphology along rows (`along_x`) or columns over nonzero bytes:
/// dilation takes any set pixel in the image-clipped window of half-side `r`, erosion needs
/// the whole window inside the image and set. Writes 1 / 0.
fn square_1d(v: &[u8], w: usize, h: usize, r: usize, along_x: bool, erode: bool) -> Vec<u8> {
    let mut out = vec![0u8; v.len()];
    out.par_chunks_mut(w.max(1))
        .enumerate()
        .for_each(|(y, row)| {
            for (x, o) in row.iter_mut().enumerate() {
                let (c, n) = if along_x { (x, w) } else { (y, h) };
                let (a, b) = (c.saturating_sub(r), (c + r).min(n - 1));
                let mut win = (a..=b).map(|t| {
                    let i = if along_x { y * w + t } else { t * w + x };
                    v[i] != 0
                });
                *o = if erode {
                    c >= r && c + r < n && win.all(|s| s)
                } else {
                    win.any(|s| s)
                } as u8;
            }
        });
    out
}

/// Share of a polyline's points that fall on the mask (W·H bytes, non-zero on it): below ½
/// a stroke "lies mostly off the hair" for `analyze`'s warning and `mask_overlay.png`.
pub fn share_on(pts: &[[f32; 2]], mask: &[u8], w: u32, h: u32) -> f32 {
    let on = pts
        .iter()
        .filter(|p| {
            let (x, y) = (p[0].floor(), p[1].floor());
            x >= 0.0 && y >= 0.0 && x < w as f32 && y < h as f32 && {
                mask[(y as u32 * w + x as u32) as usize] != 0
            }
        })
        .count();
    on as f32 / pts.len().max(1) as f32
}

/// `mask` (nonzero = set) grown by `r` pixels in a (2r+1)² square (separable). Writes 1 / 0.
pub fn dilate(mask: &[u8], w: usize, h: usize, r: usize) -> Vec<u8> {
    square_1d(
        &square_1d(mask, w, h, r, true, false),
        w,
        h,
        r,
        false,
        false,
    )
}

/// Pixels whose Chebyshev distance to the nearest unset pixel or the image border is more
/// than `r`: `mask` (nonzero = set) shrunk by a (2r+1)² square (separable). Writes 1 / 0.
pub fn erode(mask: &[u8], w: usize, h: usize, r: usize) -> Vec<u8> {
    square_1d(&square_1d(mask, w, h, r, true, true), w, h, r, false, true)
}

/// Sets the holes of `m` (w x h): 4-connected unset regions that do not touch the image
/// border and are smaller than `max_share` of the image.
pub fn fill_holes(m: &mut [bool], w: usize, h: usize, max_share: f64) {
    let mut fill = Vec::new();
    for_each_component(m, w, h, false, false, |comp, border| {
        if !border && (comp.len() as f64) < max_share * (w * h) as f64 {
            fill.extend_from_slice(comp);
        }
    });
    for k in fill {
        m[k] = true;
    }
}

/// Calls `f(pixels, touches_border)` for every connected component of the pixels equal to
/// `value` (8-connected when `eight`, else 4-connected). `m` is read as it is on entry, so
/// the caller may collect changes and apply them afterwards.
pub fn for_each_component(
    m: &[bool],
    w: usize,
    h: usize,
    value: bool,
    eight: bool,
    mut f: impl FnMut(&[usize], bool),
) {
    const N8: [(i64, i64); 8] = [
        (-1, 0),
        (1, 0),
        (0, -1),
        (0, 1),
        (-1, -1),
        (1, -1),
        (-1, 1),
        (1, 1),
    ];
    let nbrs = if eight { &N8[..] } else { &N8[..4] };
    let mut seen = vec![false; m.len()];
    let mut comp = Vec::new();
    for start in 0..m.len() {
        if seen[start] || m[start] != value {
            continue;
        }
        comp.clear();
        comp.push(start);
        seen[start] = true;
        let mut border = false;
        let mut i = 0;
        while i < comp.len() {
            let k = comp[i];
            i += 1;
            let (x, y) = (k % w, k / w);
            border |= x == 0 || y == 0 || x + 1 == w || y + 1 == h;
            for &(dx, dy) in nbrs {
                let (nx, ny) = (x as i64 + dx, y as i64 + dy);
                if nx < 0 || ny < 0 || nx >= w as i64 || ny >= h as i64 {
                    continue;
                }
                let j = ny as usize * w + nx as usize;
                if !seen[j] && m[j] == value {
                    seen[j] = true;
                    comp.push(j);
                }
            }
        }
        f(&comp, border);
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn grid(rows: &[&str]) -> (Vec<bool>, usize, usize) {
        let m = rows
            .iter()
            .flat_map(|r| r.bytes().map(|b| b == b'#'))
            .collect();
        (m, rows[0].len(), rows.len())
    }

    #[test]
    fn fill_holes_fills_enclosed_small_regions_only() {
        // A 1-px hole and a 2-px one inside; a gap open to the border stays.
        let (mut m, w, h) = grid(&["######", "#.#..#", "######", "#.####"]);
        fill_holes(&mut m, w, h, 0.1);
        let (want, _, _) = grid(&["######", "######", "######", "#.####"]);
        assert_eq!(m, want);
        // Under the size limit (2 px is not < 0.05 · 24) the larger hole stays.
        let (mut m, w, h) = grid(&["######", "#.#..#", "######", "#.####"]);
        fill_holes(&mut m, w, h, 0.05);
        let (want, _, _) = grid(&["######", "###..#", "######", "#.####"]);
        assert_eq!(m, want);
    }

    #[test]
    fn disc_offsets() {
        assert_eq!(disc(1.0, false).len(), 5);
        assert_eq!(disc(1.0, true), vec![(0, 0)]);
        assert_eq!(disc(1.5, false).len(), 9);
    }

    #[test]
    fn disc_morphology_and_border_value() {
        let (m, w, h) = grid(&["#....", ".....", "....."]);
        let d = dilate_by(&m, w, h, &disc(1.0, false), false);
        assert_eq!(d.iter().filter(|&&b| b).count(), 3);
        let (full, w, h) = grid(&["###", "###", "###"]);
        let e = erode_by(&full, w, h, &disc(1.0, false), false);
        assert_eq!(e, grid(&["...", ".#.", "..."]).0);
        assert_eq!(erode_by(&full, w, h, &disc(1.0, false), true), full);
        // Empty offsets leave the pixel itself.
        assert_eq!(erode_by(&m, 5, 3, &[], false), m);
    }

    #[test]
    fn square_morphology() {
        let (m, w, h) = grid(&[".....", "..#..", "....."]);
        let b: Vec<u8> = m.iter().map(|&s| s as u8).collect();
        let d = dilate(&b, w, h, 1);
        assert_eq!(d, [0, 1, 1, 1, 0].repeat(3));
        let e = erode(&d, w, h, 1);
        assert_eq!(e, [0, 0, 0, 0, 0, 0, 0, 1, 0, 0, 0, 0, 0, 0, 0]);
        assert_eq!(erode(&d, w, h, 0), d);
    }

    #[test]
    fn components_by_connectivity() {
        let (m, w, h) = grid(&["#...", ".#..", "...#", "...#"]);
        let mut sizes = Vec::new();
        for_each_component(&m, w, h, true, false, |c, _| sizes.push(c.len()));
        assert_eq!(sizes, [1, 1, 2]);
        sizes.clear();
        for_each_component(&m, w, h, true, true, |c, _| sizes.push(c.len()));
        assert_eq!(sizes, [2, 2]);
        let (ring, w, h) = grid(&["#####", "#...#", "#####"]);
        let mut holes = Vec::new();
        for_each_component(&ring, w, h, false, false, |c, border| {
            holes.push((c.len(), border))
        });
        assert_eq!(holes, [(3, false)]);
    }
}
