//! Small image filters on row-major f32 planes.

/// Mean over the (2r+1)² window around each pixel of `v` (w × h, row-major), clipped to the
/// image: a row pass then a column pass, each summing its window in order (so callers that
/// compare bits get the same bits every time).
pub fn box_mean(v: &[f32], w: usize, h: usize, r: usize) -> Vec<f32> {
    let mut tmp = vec![0.0f32; w * h];
    for y in 0..h {
        let row = &v[y * w..(y + 1) * w];
        for x in 0..w {
            let (a, b) = (x.saturating_sub(r), (x + r).min(w - 1));
            tmp[y * w + x] = row[a..=b].iter().sum::<f32>() / (b - a + 1) as f32;
        }
    }
    let mut out = vec![0.0f32; w * h];
    for y in 0..h {
        let (a, b) = (y.saturating_sub(r), (y + r).min(h - 1));
        for x in 0..w {
            let s: f32 = (a..=b).map(|yy| tmp[yy * w + x]).sum();
            out[y * w + x] = s / (b - a + 1) as f32;
        }
    }
    out
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn box_mean_clips_at_the_border() {
        // 3x2 plane; r = 1: every window is clipped.
        let v = [1.0, 2.0, 3.0, 4.0, 5.0, 6.0];
        let m = box_mean(&v, 3, 2, 1);
        assert_eq!(m[0], (1.0 + 2.0 + 4.0 + 5.0) / 4.0);
        assert_eq!(m[1], (1.0 + 2.0 + 3.0 + 4.0 + 5.0 + 6.0) / 6.0);
        assert_eq!(box_mean(&v, 3, 2, 0), v.to_vec());
    }
}
