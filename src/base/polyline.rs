//! Polyline measures shared by the stages that walk strands by arc length.

/// Cumulative arc length at every vertex (f64, 0 at the first; one entry for a point).
pub fn arc_lengths(p: &[[f32; 3]]) -> Vec<f64> {
    let mut acc = Vec::with_capacity(p.len().max(1));
    acc.push(0.0f64);
    for w in p.windows(2) {
        let d: f64 = (0..3).map(|k| ((w[1][k] - w[0][k]) as f64).powi(2)).sum();
        acc.push(acc[acc.len() - 1] + d.sqrt());
    }
    acc
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn lengths_accumulate() {
        assert_eq!(arc_lengths(&[[0.0; 3]]), vec![0.0]);
        let a = arc_lengths(&[[0.0; 3], [3.0, 4.0, 0.0], [3.0, 4.0, 1.0]]);
        assert_eq!(a, vec![0.0, 5.0, 6.0]);
    }
}
