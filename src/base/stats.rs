//! Order statistics of float samples.

/// How a quantile `q` picks its rank among `n` sorted samples.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Rank {
    /// ⌊n·q⌋ (in f64), capped at n − 1.
    Floor,
    /// round((n − 1)·q) (in f32, q clamped to [0, 1]).
    Round,
}

/// The sample of rank `q` under the total float order (NaNs sort by sign to the ends), or
/// `None` when `v` is empty. Reorders `v`.
pub fn quantile(v: &mut [f32], q: f64, rank: Rank) -> Option<f32> {
    if v.is_empty() {
        return None;
    }
    let n = v.len();
    let k = match rank {
        Rank::Floor => ((n as f64 * q) as usize).min(n - 1),
        Rank::Round => ((n - 1) as f32 * (q as f32).clamp(0.0, 1.0)).round() as usize,
    };
    let (_, x, _) = v.select_nth_unstable_by(k, f32::total_cmp);
    Some(*x)
}

/// Value below which `frac` of the finite samples lie (for robust normalisation); 0 when
/// there are none.
pub fn percentile(data: &[f32], frac: f32) -> f32 {
    let mut v: Vec<f32> = data.iter().copied().filter(|x| x.is_finite()).collect();
    quantile(&mut v, frac as f64, Rank::Round).unwrap_or(0.0)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn ranks_and_finite_filter() {
        let mut v = [4.0, 1.0, 3.0, 2.0];
        assert_eq!(quantile(&mut v, 0.5, Rank::Floor), Some(3.0));
        assert_eq!(quantile(&mut v, 1.0, Rank::Floor), Some(4.0));
        assert_eq!(quantile(&mut v, 0.5, Rank::Round), Some(3.0));
        assert_eq!(quantile(&mut v, 0.4, Rank::Round), Some(2.0));
        assert_eq!(quantile(&mut [], 0.5, Rank::Floor), None);
        assert_eq!(percentile(&[f32::NAN, 2.0, f32::INFINITY, 1.0], 1.0), 2.0);
        assert_eq!(percentile(&[f32::NAN], 0.5), 0.0);
    }
}
