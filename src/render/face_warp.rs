//! The head layer fitted to the width of the photo's face (issue 19, novel views).
//!
//! The parametric head fitted to a few landmarks rarely has the photo's face width. Where it
//! is narrower (the synthetic case's jaw and cheeks), those face pixels are in the
//! inpainting's hole, and a novel view showed them as backdrop-coloured patches inside the
//! face's outline (pitch ±10). Where it is wider and the photo shows backdrop beside the
//! face (the astronaut's cheeks), the texture's alpha cut the head's side away, and a
//! turned view looked through the head at the backdrop beside the turned cheek.
//! [`FaceWarp`] measures, per photo row from above the eyes to the chin, how far the
//! photo's face runs past the head's outline on each side, or how far short of it it ends
//! with backdrop (not hair: the head goes on under hair) in between, and stretches or
//! squeezes the outer half of the head's span to match, at the depth each point already
//! has. The layer's silhouette then follows the photo's face, and its texture is taken
//! through the same map, so at the photo's own view every texel still shows the photo pixel
//! it lands on. The inner half of the span (eyes, nose, mouth) does not move.

use crate::hair::head::{Head, WeakPerspective};
use glam::Vec3;

/// How far the layer may stretch past (or squeeze inside) the fitted outline, as a share of
/// the half span: a face mask that leaks (a hand, a collar of skin colour) cannot balloon
/// the head, nor a ragged one pinch it.
const MAX_REACH: f32 = 0.3;
/// Half windows (rows) of the median, then the mean, that smooth the reach down the face.
const MEDIAN_ROWS: usize = 3;
const MEAN_ROWS: usize = 4;
/// Share of the half span that stays put about the face's centre line.
const INNER: f32 = 0.5;
/// Rows above the eyes that are stretched, as a share of the eyes-to-chin height, with the
/// reach tapering to none at the top (the temples are mostly hair).
const ABOVE_EYES: f32 = 0.5;

/// Per photo row, the map of image x that fits the head layer's width (see the module notes).
#[derive(Clone, Debug)]
pub struct FaceWarp {
    /// Per row: the centre line's x, and per side (left, right) the head's half span at
    /// that row and how far past it the photo's face reaches (0: no change), px.
    rows: Vec<Option<Row>>,
}

#[derive(Clone, Copy, Debug)]
struct Row {
    cx: f32,
    half: [f32; 2],
    reach: [f32; 2],
}

impl Row {
    fn map(&self, x: f32) -> f32 {
        let d = x - self.cx;
        let side = (d > 0.0) as usize;
        let (m, e) = (self.half[side], self.reach[side]);
        let k = INNER * m;
        if e == 0.0 || m <= 1.0 || d.abs() <= k {
            return x;
        }
        let stretched = k + (d.abs() - k) * (m + e - k) / (m - k);
        self.cx + stretched.copysign(d)
    }
}

impl FaceWarp {
    /// The identity (no row changes).
    pub fn identity() -> FaceWarp {
        FaceWarp { rows: Vec::new() }
    }

    /// Measures the map from `covered` (photo pixels the fitted head covers at the photo's
    /// view), `face` (the photo's face pixels: skin and the inner face) and `hair` (the hair
    /// mask as the layers grow it), all w x h.
    /// The identity when the head has no eyes or chin landmarks, or a mask is not w x h.
    pub fn fit(
        covered: &[bool],
        face: &[u8],
        hair: &[u8],
        w: usize,
        h: usize,
        head: &Head,
        cam: &WeakPerspective,
    ) -> FaceWarp {
        if [covered.len(), face.len(), hair.len()]
            .iter()
            .any(|&n| n != w * h)
        {
            return FaceWarp::identity();
        }
        let at = |n: &str| head.landmark(n).map(|p| cam.project(p).truncate());
        let (Some(le), Some(re), Some(chin)) = (at("left_eye"), at("right_eye"), at("chin")) else {
            return FaceWarp::identity();
        };
        let eyes = 0.5 * (le + re);
        let span = chin.y - eyes.y;
        if !(span.is_finite() && span > 2.0) {
            return FaceWarp::identity();
        }
        let top = eyes.y - ABOVE_EYES * span;
        // The centre line from the eyes' midpoint to the chin (a tilted head leans it).
        let centre = |y: f32| eyes.x + (chin.x - eyes.x) * (y - eyes.y) / span;
        let mut raw: Vec<Option<Row>> = vec![None; h];
        for (y, slot) in raw.iter_mut().enumerate() {
            let yc = y as f32 + 0.5;
            if yc < top || yc > chin.y {
                continue;
            }
            let cx = centre(yc);
            if !(cx >= 0.0 && cx < w as f32) {
                continue;
            }
            let row = y * w;
            let c = cx as usize;
            if !covered[row + c] {
                continue;
            }
            // The head's run through the centre line, then the photo's face run on from
            // each of its ends.
            let mut l = c;
            while l > 0 && covered[row + l - 1] {
                l -= 1;
            }
            let mut r = c;
            while r + 1 < w && covered[row + r + 1] {
                r += 1;
            }
            let mut fl = l;
            while fl > 0 && face[row + fl - 1] != 0 {
                fl -= 1;
            }
            let mut fr = r;
            while fr + 1 < w && face[row + fr + 1] != 0 {
                fr += 1;
            }
            // Past the head's edge: how far the photo's face runs on. Short of it: how far
            // in the face ends, when backdrop (not hair, under which the head goes on)
            // lies between the two.
            let reach = |edge: usize, far: usize, toward_centre: &dyn Fn(usize) -> usize| {
                if face[row + edge] != 0 {
                    return far.abs_diff(edge) as f32;
                }
                let mut x = edge;
                while face[row + x] == 0 {
                    // Hair: the head goes on under it. The centre line reached: no face on
                    // this row to fit to.
                    if hair[row + x] != 0 || x == c {
                        return 0.0;
                    }
                    x = toward_centre(x);
                }
                -(x.abs_diff(edge) as f32)
            };
            let half = [cx - l as f32, r as f32 + 1.0 - cx];
            let taper = ((yc - top) / (eyes.y - top)).clamp(0.0, 1.0);
            let e = [reach(l, fl, &|x| x + 1), reach(r, fr, &|x| x - 1)];
            let e = [0, 1].map(|s| (taper * e[s]).clamp(-MAX_REACH * half[s], MAX_REACH * half[s]));
            *slot = Some(Row { cx, half, reach: e });
        }
        // Rows smoothed (a 7-row median, then a 9-row mean) so the outline has no steps
        // of its own where the face mask's edge is ragged.
        let reach_of = |y: usize, s: usize| raw[y].map_or(0.0, |r| r.reach[s]);
        let median: Vec<[f32; 2]> = (0..h)
            .map(|y| {
                [0, 1].map(|s| {
                    let mut v: Vec<f32> = (y.saturating_sub(MEDIAN_ROWS)
                        ..(y + MEDIAN_ROWS + 1).min(h))
                        .map(|k| reach_of(k, s))
                        .collect();
                    v.sort_by(f32::total_cmp);
                    v[v.len() / 2]
                })
            })
            .collect();
        let rows = (0..h)
            .map(|y| {
                let Row { cx, half, .. } = raw[y]?;
                let win = y.saturating_sub(MEAN_ROWS)..(y + MEAN_ROWS + 1).min(h);
                let n = win.len() as f32;
                let reach = [0, 1].map(|s| {
                    let m: f32 = win.clone().map(|k| median[k][s]).sum::<f32>() / n;
                    m.clamp(-MAX_REACH * half[s], MAX_REACH * half[s])
                });
                Some(Row { cx, half, reach })
            })
            .collect();
        FaceWarp { rows }
    }

    /// Whether no row changes (the layer needs no such check: rows the map leaves alone
    /// are copied as they are).
    #[cfg(test)]
    fn is_identity(&self) -> bool {
        self.rows
            .iter()
            .all(|r| r.is_none_or(|r| r.reach.iter().all(|&e| e == 0.0)))
    }

    /// Image x of a point on photo row `y` (continuous, pixel centres at +0.5) after the
    /// map: the two nearest rows' maps, blended.
    pub fn map_x(&self, x: f32, y: f32) -> f32 {
        let f = y - 0.5;
        if !(f.is_finite() && x.is_finite()) || self.rows.is_empty() {
            return x;
        }
        let r0 = f.floor();
        let a = f - r0;
        let at = |r: f32| {
            if r < 0.0 || r >= self.rows.len() as f32 {
                return x;
            }
            self.rows[r as usize].map_or(x, |row| row.map(x))
        };
        (1.0 - a) * at(r0) + a * at(r0 + 1.0)
    }

    /// A projected point (image x, image y, depth) moved by the map.
    pub fn map(&self, q: Vec3) -> Vec3 {
        Vec3::new(self.map_x(q.x, q.y), q.y, q.z)
    }

    /// `img` (w x h) pulled through the map: pixel (x, y) takes `img` at the mapped x of its
    /// centre (linear between the two nearest pixels), so a texel that sees (x, y) in the
    /// result sees where the map puts it in `img`.
    pub fn pull<T: Copy>(
        &self,
        img: &[T],
        w: usize,
        h: usize,
        lerp: impl Fn(T, T, f32) -> T,
    ) -> Vec<T> {
        let mut out = img.to_vec();
        for y in 0..h.min(self.rows.len()) {
            // At a pixel centre's row only that row's map counts (see `map_x`).
            if self.rows[y].is_none_or(|r| r.reach.iter().all(|&e| e == 0.0)) {
                continue;
            }
            for x in 0..w {
                let sx = self.map_x(x as f32 + 0.5, y as f32 + 0.5) - 0.5;
                let x0 = sx.floor().clamp(0.0, (w - 1) as f32);
                let a = (sx - x0).clamp(0.0, 1.0);
                let (i0, i1) = (x0 as usize, (x0 as usize + 1).min(w - 1));
                out[y * w + x] = lerp(img[y * w + i0], img[y * w + i1], a);
            }
        }
        out
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn row(reach: [f32; 2]) -> Row {
        Row {
            cx: 50.0,
            half: [20.0, 20.0],
            reach,
        }
    }

    #[test]
    fn rows_stretch_the_outer_half_only_and_stay_monotone() {
        let r = row([4.0, 0.0]);
        // Inner half fixed, the left edge moved out by the reach, the right side untouched.
        assert_eq!(r.map(45.0), 45.0);
        assert!((r.map(30.0) - 26.0).abs() < 1e-5, "{}", r.map(30.0));
        assert!((r.map(40.0) - 40.0).abs() < 1e-5);
        assert_eq!(r.map(68.0), 68.0);
        let xs: Vec<f32> = (0..1000).map(|i| i as f32 * 0.1).collect();
        for p in xs.windows(2) {
            assert!(r.map(p[1]) >= r.map(p[0]), "not monotone at {}", p[0]);
        }
    }

    #[test]
    fn the_head_takes_the_faces_width_except_under_hair() {
        let head = Head::default();
        let cam = WeakPerspective::frontal(600.0, glam::Vec2::new(64.0, 80.0));
        let (w, h) = (128usize, 160usize);
        let chin = cam.project(head.landmark("chin").unwrap());
        let eye = cam.project(head.landmark("left_eye").unwrap());
        // The head covers 30 px either side of the centre; the face 36 (or 24).
        let cover = |half: f32| -> Vec<u8> {
            (0..w * h)
                .map(|i| {
                    let (x, y) = ((i % w) as f32 + 0.5, (i / w) as f32 + 0.5);
                    ((x - 64.0).abs() < half && y > eye.y - 40.0 && y < chin.y + 2.0) as u8
                })
                .collect()
        };
        let covered: Vec<bool> = cover(30.0).iter().map(|&v| v != 0).collect();
        let no_hair = vec![0u8; w * h];
        let wide = FaceWarp::fit(&covered, &cover(36.0), &no_hair, w, h, &head, &cam);
        let y = 0.5 * (eye.y + chin.y);
        // The head's left edge (x 34) lands on the face's (x 28).
        let edge = wide.map_x(34.0, y);
        assert!(
            (edge - 28.0).abs() < 0.05,
            "the left edge lands at x {edge}"
        );
        assert_eq!(wide.map_x(64.0, y), 64.0, "the centre line stays");
        // A narrower face with backdrop beside it pulls the head's edge in to its own (x 40);
        // with hair beside it (the head goes on under the hair) nothing moves.
        let narrow = FaceWarp::fit(&covered, &cover(24.0), &no_hair, w, h, &head, &cam);
        let edge = narrow.map_x(34.0, y);
        assert!(
            (edge - 40.0).abs() < 0.05,
            "the left edge lands at x {edge}"
        );
        let hair_only: Vec<u8> = (0..w * h)
            .map(|i| cover(40.0)[i] & (1 - cover(24.0)[i]))
            .collect();
        let beside_hair = FaceWarp::fit(&covered, &cover(24.0), &hair_only, w, h, &head, &cam);
        assert!(beside_hair.is_identity());
        // Above the taper and below the chin nothing moves.
        assert_eq!(wide.map_x(34.0, chin.y + 5.0), 34.0);
    }
}
