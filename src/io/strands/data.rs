//! USC-HairSalon `.data` (Hu et al.'s binary strand format).

use super::*;

pub(super) fn decode_data(b: &[u8]) -> Msg<StrandSet> {
    let mut r = Reader::new(b);
    let n = r.i32()?;
    if n <= 0 {
        return Err(format!("strand count is {n}; expected at least one strand"));
    }
    let n = n as usize;
    if n > r.remaining() / 4 {
        return Err(format!(
            "strand count {n} exceeds the file size ({} bytes)",
            b.len()
        ));
    }
    let mut counts = Vec::with_capacity(n);
    let mut points = Vec::new();
    for i in 0..n {
        let k = r.i32()?;
        if k < 1 {
            return Err(format!("strand {i} has {k} vertices"));
        }
        let k = k as usize;
        if k > r.remaining() / 12 {
            return Err(format!(
                "strand {i} has {k} vertices, more than the {} bytes left hold",
                r.remaining()
            ));
        }
        for _ in 0..k {
            points.push(r.vec3()?);
        }
        counts.push(k as u32);
    }
    if r.remaining() != 0 {
        return Err(format!(
            "{} unexpected bytes after the last strand",
            r.remaining()
        ));
    }
    Ok(StrandSet::new(points, counts))
}

pub(super) fn encode_data(s: &StrandSet) -> Msg<Vec<u8>> {
    let n = i32::try_from(s.counts.len()).map_err(|_| "too many strands for .data".to_string())?;
    let mut out = Vec::with_capacity(4 + 4 * s.counts.len() + 12 * s.points.len());
    out.extend_from_slice(&n.to_le_bytes());
    for (i, strand) in s.strands().enumerate() {
        let k = i32::try_from(strand.len())
            .map_err(|_| format!("strand {i} has too many vertices for .data"))?;
        out.extend_from_slice(&k.to_le_bytes());
        for x in strand.as_flattened() {
            out.extend_from_slice(&x.to_le_bytes());
        }
    }
    Ok(out)
}
