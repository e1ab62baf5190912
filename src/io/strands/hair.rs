//! cyHair `.hair` (Cem Yuksel's binary strand format).

use super::*;

const HAIR_SEGMENTS: u32 = 1;
const HAIR_POINTS: u32 = 2;
const HAIR_THICKNESS: u32 = 4;
const HAIR_TRANSPARENCY: u32 = 8;
const HAIR_COLORS: u32 = 16;
const HAIR_HEADER: usize = 128;

pub(super) fn decode_hair(b: &[u8]) -> Msg<StrandSet> {
    if b.len() < 4 || &b[..4] != b"HAIR" {
        return Err("not a cyHair file: magic is not \"HAIR\"".into());
    }
    if b.len() < HAIR_HEADER {
        return Err(format!(
            "truncated: the header needs {HAIR_HEADER} bytes, file has {}",
            b.len()
        ));
    }
    let mut r = Reader::new(b);
    r.pos = 4;
    let nstrands = r.u32()?;
    let npoints = r.u32()?;
    let flags = r.u32()?;
    let default_segments = r.u32()?;
    let default_thickness = r.f32()?;
    let default_transparency = r.f32()?;
    let default_color = r.vec3()?;
    r.pos = HAIR_HEADER; // skip the info text
    if flags & !31 != 0 {
        // Unknown arrays would shift every later one, so refuse rather than misread.
        return Err(format!("unknown flag bits in {flags:#x}"));
    }
    if nstrands == 0 {
        return Err("zero strands".into());
    }
    if flags & HAIR_POINTS == 0 {
        return Err("no points array (flag 2 unset)".into());
    }
    let (n, p) = (u64::from(nstrands), u64::from(npoints));
    let has = |f: u32| u64::from(flags & f != 0);
    let needed = HAIR_HEADER as u64
        + has(HAIR_SEGMENTS) * 2 * n
        + 12 * p
        + has(HAIR_THICKNESS) * 4 * p
        + has(HAIR_TRANSPARENCY) * 4 * p
        + has(HAIR_COLORS) * 12 * p;
    if needed != b.len() as u64 {
        return Err(format!(
            "header says {n} strands and {p} points (flags {flags}), needing {needed} bytes; file has {}",
            b.len()
        ));
    }
    // The size check bounds p (12 bytes each); bound n the same way before allocating.
    let counts: Vec<u32> = if flags & HAIR_SEGMENTS != 0 {
        (0..n)
            .map(|_| r.u16().map(|s| u32::from(s) + 1))
            .collect::<Msg<_>>()?
    } else {
        let per = u64::from(default_segments) + 1;
        if n * per != p {
            return Err(format!(
                "{n} strands of {per} points (default segments) do not make {p} points"
            ));
        }
        vec![per as u32; n as usize]
    };
    let total: u64 = counts.iter().map(|&c| u64::from(c)).sum();
    if total != p {
        return Err(format!(
            "segment counts give {total} points but the header says {p}"
        ));
    }
    let p = p as usize;
    let points = (0..p).map(|_| r.vec3()).collect::<Msg<Vec<_>>>()?;
    let mut scalars = |flag: u32, default: f32| -> Msg<Vec<f32>> {
        if flags & flag != 0 {
            (0..p).map(|_| r.f32()).collect()
        } else {
            Ok(vec![default; p])
        }
    };
    let thickness = scalars(HAIR_THICKNESS, default_thickness)?;
    let transparency = scalars(HAIR_TRANSPARENCY, default_transparency)?;
    let colors = if flags & HAIR_COLORS != 0 {
        (0..p).map(|_| r.vec3()).collect::<Msg<Vec<_>>>()?
    } else {
        vec![default_color; p]
    };
    // cyHair's header defaults are the file's stated values, so they become per-vertex data.
    Ok(StrandSet {
        points,
        counts,
        thickness: Some(thickness),
        transparency: Some(transparency),
        colors: Some(colors),
    })
}

pub(super) fn encode_hair(s: &StrandSet) -> Msg<Vec<u8>> {
    let nstrands = u32::try_from(s.counts.len())
        .map_err(|_| format!(".hair holds at most {} strands", u32::MAX))?;
    let npoints = u32::try_from(s.points.len())
        .map_err(|_| format!(".hair holds at most {} points", u32::MAX))?;
    let mut segments = Vec::with_capacity(s.counts.len());
    for (i, &c) in s.counts.iter().enumerate() {
        let seg = u16::try_from(c - 1).map_err(|_| {
            format!(
                "strand {i} has {c} vertices; .hair stores at most 65536 per strand (u16 segment count)"
            )
        })?;
        segments.push(seg);
    }
    // An array whose values are all equal goes in the header default instead: same values
    // on read, and cyHair readers expect exactly that.
    let mut flags = HAIR_SEGMENTS | HAIR_POINTS;
    let mut default_thickness = 1.0f32;
    let mut default_transparency = 0.0f32;
    let mut default_color = [1.0f32; 3];
    let mut per_vertex = |v: &Option<Vec<f32>>, default: &mut f32, flag: u32| match v {
        Some(v) if uniform(v) => *default = v[0],
        Some(_) => flags |= flag,
        None => {}
    };
    per_vertex(&s.thickness, &mut default_thickness, HAIR_THICKNESS);
    per_vertex(
        &s.transparency,
        &mut default_transparency,
        HAIR_TRANSPARENCY,
    );
    if let Some(c) = &s.colors {
        if c.iter()
            .all(|x| x.map(f32::to_bits) == c[0].map(f32::to_bits))
        {
            default_color = c[0];
        } else {
            flags |= HAIR_COLORS;
        }
    }
    let mut out = Vec::with_capacity(HAIR_HEADER + segments.len() * 2 + s.points.len() * 32);
    out.extend_from_slice(b"HAIR");
    for v in [nstrands, npoints, flags, 0] {
        out.extend_from_slice(&v.to_le_bytes());
    }
    for v in [default_thickness, default_transparency]
        .into_iter()
        .chain(default_color)
    {
        out.extend_from_slice(&v.to_le_bytes());
    }
    let mut info = [0u8; 88];
    let text = b"written by coif";
    info[..text.len()].copy_from_slice(text);
    out.extend_from_slice(&info);
    debug_assert_eq!(out.len(), HAIR_HEADER);
    for seg in segments {
        out.extend_from_slice(&seg.to_le_bytes());
    }
    let put = |out: &mut Vec<u8>, v: &[f32]| {
        v.iter()
            .for_each(|x| out.extend_from_slice(&x.to_le_bytes()))
    };
    put(&mut out, s.points.as_flattened());
    if flags & HAIR_THICKNESS != 0 {
        put(&mut out, s.thickness.as_deref().unwrap_or_default());
    }
    if flags & HAIR_TRANSPARENCY != 0 {
        put(&mut out, s.transparency.as_deref().unwrap_or_default());
    }
    if flags & HAIR_COLORS != 0 {
        put(
            &mut out,
            s.colors.as_deref().unwrap_or_default().as_flattened(),
        );
    }
    Ok(out)
}
