//! What the comb and cut passes share (`wgsl/shared/edit_stroke.wgsl` on the GPU side): the
//! stroke as a list of segments with their end tangents, the nearest stroke point of an
//! image point, the weak-perspective projection and the per-strand hash.

/// Floats per stroke segment in the `segs` buffer: a.x a.y ta.x ta.y b.x b.y tb.x tb.y
/// (ends in image px, unit tangents of the stroke at both ends).
pub const SEG_FLOATS: usize = 8;

/// Segments of the strokes (image px) packed for the passes. The tangent at stroke vertex
/// j is the unit vector from γ_{j−1} to γ_{j+1} (C13 A.1), one-sided at the ends; repeated
/// points are dropped first so no tangent is undefined. Strokes are never joined to each
/// other.
pub fn pack_segments(strokes: &[Vec<[f32; 2]>]) -> Vec<f32> {
    let mut out = Vec::new();
    for s in strokes {
        let mut pts: Vec<[f32; 2]> = Vec::with_capacity(s.len());
        for p in s {
            if pts.last() != Some(p) {
                pts.push(*p);
            }
        }
        if pts.len() < 2 {
            continue;
        }
        let n = pts.len();
        let tan: Vec<[f32; 2]> = (0..n)
            .map(|j| {
                let a = pts[j.saturating_sub(1)];
                let b = pts[(j + 1).min(n - 1)];
                let d = [b[0] - a[0], b[1] - a[1]];
                let l = (d[0] * d[0] + d[1] * d[1]).sqrt();
                if l > 0.0 {
                    [d[0] / l, d[1] / l]
                } else {
                    // γ_{j−1} = γ_{j+1} (the stroke doubles back at an interior vertex):
                    // the outgoing direction, never zero once repeats are gone.
                    let d = [pts[j + 1][0] - pts[j][0], pts[j + 1][1] - pts[j][1]];
                    let l = (d[0] * d[0] + d[1] * d[1]).sqrt();
                    [d[0] / l, d[1] / l]
                }
            })
            .collect();
        for j in 0..n - 1 {
            out.extend_from_slice(&[
                pts[j][0],
                pts[j][1],
                tan[j][0],
                tan[j][1],
                pts[j + 1][0],
                pts[j + 1][1],
                tan[j + 1][0],
                tan[j + 1][1],
            ]);
        }
    }
    out
}

/// The nearest stroke point of `p`: (distance px, unit stroke direction there). The
/// direction is the end tangents interpolated linearly along the segment and normalised
/// (the segment's own direction if they cancel). Ties keep the first segment, as the
/// shader does.
pub fn nearest(segs: &[f32], n_segs: u32, p: [f32; 2]) -> (f32, [f32; 2]) {
    let mut best = 3.0e38f32;
    let mut found = false;
    let mut dir = [1.0f32, 0.0];
    for i in 0..n_segs as usize {
        let g = &segs[SEG_FLOATS * i..SEG_FLOATS * (i + 1)];
        let ab = [g[4] - g[0], g[5] - g[1]];
        let ap = [p[0] - g[0], p[1] - g[1]];
        let l2 = ab[0] * ab[0] + ab[1] * ab[1];
        let mut u = 0.0f32;
        if l2 > 0.0 {
            u = ((ap[0] * ab[0] + ap[1] * ab[1]) / l2).clamp(0.0, 1.0);
        }
        let q = [ap[0] - u * ab[0], ap[1] - u * ab[1]];
        let d2 = q[0] * q[0] + q[1] * q[1];
        if !found || d2 < best {
            found = true;
            best = d2;
            let t = [g[2] + u * (g[6] - g[2]), g[3] + u * (g[7] - g[3])];
            let tl = (t[0] * t[0] + t[1] * t[1]).sqrt();
            let al = l2.sqrt();
            dir = if tl > 1e-6 {
                [t[0] / tl, t[1] / tl]
            } else if al > 0.0 {
                [ab[0] / al, ab[1] / al]
            } else {
                [g[2], g[3]]
            };
        }
    }
    if !found {
        return (3.0e38, dir);
    }
    (best.sqrt(), dir)
}

/// Whether the image segments p0–p1 and a–b cross (the sign tests are half-open, as in the
/// shader, so a crossing through a shared end counts once).
pub fn crosses(p0: [f32; 2], p1: [f32; 2], a: [f32; 2], b: [f32; 2]) -> bool {
    let cross = |o: [f32; 2], u: [f32; 2], v: [f32; 2]| {
        (u[0] - o[0]) * (v[1] - o[1]) - (u[1] - o[1]) * (v[0] - o[0])
    };
    let d1 = cross(a, b, p0) > 0.0;
    let d2 = cross(a, b, p1) > 0.0;
    let d3 = cross(p0, p1, a) > 0.0;
    let d4 = cross(p0, p1, b) > 0.0;
    d1 != d2 && d3 != d4
}

/// Model point → image px through the camera rows `r0`, `r1` (view x and y), the scale `s`
/// and the image position `t` of the origin (image y points down).
pub fn project(r0: [f32; 3], r1: [f32; 3], s: f32, t: [f32; 2], p: [f32; 3]) -> [f32; 2] {
    let vx = r0[0] * p[0] + r0[1] * p[1] + r0[2] * p[2];
    let vy = r1[0] * p[0] + r1[1] * p[1] + r1[2] * p[2];
    [s * vx + t[0], -s * vy + t[1]]
}

/// PCG hash (O'Neill 2014, the RXS-M-XS output of one LCG step): the same integers on both
/// backends.
pub fn pcg(v: u32) -> u32 {
    let state = v.wrapping_mul(747_796_405).wrapping_add(2_891_336_453);
    let word = ((state >> ((state >> 28) + 4)) ^ state).wrapping_mul(277_803_737);
    (word >> 22) ^ word
}

/// A uniform draw in [0, 1) for strand `strand` under the 64-bit seed (lo, hi): 24 bits, so
/// the float is exact on both backends.
pub fn strand_uniform(seed_lo: u32, seed_hi: u32, strand: u32) -> f32 {
    let h = pcg(pcg(seed_lo ^ pcg(seed_hi)).wrapping_add(strand));
    (h >> 8) as f32 * (1.0 / 16_777_216.0)
}
