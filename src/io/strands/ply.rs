//! PLY strands, ascii and binary: vertex + strand (vertex counts) or edge elements.

use super::*;
use std::fmt::Write as _;

#[derive(Debug, Clone, Copy, PartialEq)]
enum PlyEncoding {
    Ascii,
    BinaryLe,
    BinaryBe,
}

#[derive(Debug, Clone, Copy, PartialEq)]
enum Scalar {
    I8,
    U8,
    I16,
    U16,
    I32,
    U32,
    F32,
    F64,
}

impl Scalar {
    fn parse(t: &str) -> Option<Scalar> {
        Some(match t {
            "char" | "int8" => Scalar::I8,
            "uchar" | "uint8" => Scalar::U8,
            "short" | "int16" => Scalar::I16,
            "ushort" | "uint16" => Scalar::U16,
            "int" | "int32" => Scalar::I32,
            "uint" | "uint32" => Scalar::U32,
            "float" | "float32" => Scalar::F32,
            "double" | "float64" => Scalar::F64,
            _ => return None,
        })
    }

    fn size(self) -> usize {
        match self {
            Scalar::I8 | Scalar::U8 => 1,
            Scalar::I16 | Scalar::U16 => 2,
            Scalar::I32 | Scalar::U32 | Scalar::F32 => 4,
            Scalar::F64 => 8,
        }
    }

    fn is_float(self) -> bool {
        matches!(self, Scalar::F32 | Scalar::F64)
    }

    /// Full-scale value of an integer colour channel.
    fn max(self) -> f64 {
        match self {
            Scalar::I8 => 127.0,
            Scalar::U8 => 255.0,
            Scalar::I16 => 32767.0,
            Scalar::U16 => 65535.0,
            Scalar::I32 => i32::MAX as f64,
            Scalar::U32 => u32::MAX as f64,
            Scalar::F32 | Scalar::F64 => 1.0,
        }
    }

    fn read_bin(self, r: &mut Reader) -> Msg<f64> {
        Ok(match self {
            Scalar::I8 => f64::from(i8::from_le_bytes(r.take()?)),
            Scalar::U8 => f64::from(u8::from_le_bytes(r.take()?)),
            Scalar::I16 => f64::from(i16::from_le_bytes(r.take()?)),
            Scalar::U16 => f64::from(u16::from_le_bytes(r.take()?)),
            Scalar::I32 => f64::from(i32::from_le_bytes(r.take()?)),
            Scalar::U32 => f64::from(u32::from_le_bytes(r.take()?)),
            Scalar::F32 => f64::from(f32::from_le_bytes(r.take()?)),
            Scalar::F64 => f64::from_le_bytes(r.take()?),
        })
    }

    fn parse_ascii(self, tok: &str) -> Option<f64> {
        // Floats parse as their own width so an ascii f32 is the f32 a binary file would hold.
        match self {
            Scalar::F32 => tok.parse::<f32>().ok().map(f64::from),
            Scalar::F64 => tok.parse::<f64>().ok(),
            _ => {
                let v = tok.parse::<i64>().ok()?;
                let (lo, hi) = match self {
                    Scalar::I8 => (i8::MIN as i64, i8::MAX as i64),
                    Scalar::U8 => (0, u8::MAX as i64),
                    Scalar::I16 => (i16::MIN as i64, i16::MAX as i64),
                    Scalar::U16 => (0, u16::MAX as i64),
                    Scalar::I32 => (i32::MIN as i64, i32::MAX as i64),
                    _ => (0, u32::MAX as i64),
                };
                (lo..=hi).contains(&v).then_some(v as f64)
            }
        }
    }
}

#[derive(Debug)]
enum PropKind {
    Scalar(Scalar),
    List { count: Scalar, item: Scalar },
}

#[derive(Debug)]
struct Prop {
    name: String,
    kind: PropKind,
}

#[derive(Debug)]
struct Element {
    name: String,
    count: usize,
    props: Vec<Prop>,
}

/// Scalar columns of one element (list properties are skipped: strands need none).
struct Table {
    cols: Vec<Option<(Scalar, Vec<f64>)>>,
}

impl Table {
    fn col<'t>(&'t self, el: &Element, name: &str) -> Option<(Scalar, &'t [f64])> {
        let i = el.props.iter().position(|p| p.name == name)?;
        self.cols[i].as_ref().map(|(t, v)| (*t, v.as_slice()))
    }
}

/// Parses the header; returns the encoding, the elements and the offset of the body.
fn parse_ply_header(b: &[u8]) -> Msg<(PlyEncoding, Vec<Element>, usize)> {
    if !(b.starts_with(b"ply\n") || b.starts_with(b"ply\r\n")) {
        return Err("not a PLY file: first line is not \"ply\"".into());
    }
    let mut pos = 0usize;
    let mut encoding = None;
    let mut elements: Vec<Element> = Vec::new();
    loop {
        let Some(len) = b[pos..].iter().position(|&c| c == b'\n') else {
            return Err("malformed PLY header: no end_header line".into());
        };
        let line = std::str::from_utf8(&b[pos..pos + len])
            .map_err(|_| "malformed PLY header: not ASCII text".to_string())?;
        pos += len + 1;
        let toks: Vec<&str> = line.split_ascii_whitespace().collect();
        let bad = || format!("malformed PLY header line {line:?}");
        match toks.as_slice() {
            ["ply"] if pos <= 5 => {}
            ["end_header"] => break,
            ["comment", ..] | ["obj_info", ..] => {}
            [] => {}
            ["format", f, v] => {
                if !v.starts_with('1') {
                    return Err(format!("unsupported PLY version {v}"));
                }
                encoding = Some(match *f {
                    "ascii" => PlyEncoding::Ascii,
                    "binary_little_endian" => PlyEncoding::BinaryLe,
                    "binary_big_endian" => PlyEncoding::BinaryBe,
                    _ => return Err(format!("unknown PLY format {f:?}")),
                });
            }
            ["element", name, count] => {
                let count: usize = count.parse().map_err(|_| bad())?;
                if elements.iter().any(|e| e.name == *name) {
                    return Err(format!("malformed PLY header: element {name} twice"));
                }
                elements.push(Element {
                    name: name.to_string(),
                    count,
                    props: Vec::new(),
                });
            }
            ["property", "list", ct, it, name] => {
                let (Some(count), Some(item)) = (Scalar::parse(ct), Scalar::parse(it)) else {
                    return Err(bad());
                };
                if count.is_float() {
                    return Err(bad());
                }
                add_prop(&mut elements, name, PropKind::List { count, item }, line)?;
            }
            ["property", t, name] => {
                let t = Scalar::parse(t).ok_or_else(bad)?;
                add_prop(&mut elements, name, PropKind::Scalar(t), line)?;
            }
            _ => return Err(bad()),
        }
    }
    let encoding = encoding.ok_or("malformed PLY header: no format line")?;
    if let Some(e) = elements.iter().find(|e| e.props.is_empty() && e.count > 0) {
        // Rows without properties take no bytes, so their count could spin forever.
        return Err(format!(
            "malformed PLY header: element {} has no properties",
            e.name
        ));
    }
    Ok((encoding, elements, pos))
}

fn add_prop(elements: &mut [Element], name: &str, kind: PropKind, line: &str) -> Msg<()> {
    let Some(el) = elements.last_mut() else {
        return Err(format!("malformed PLY header: {line:?} before any element"));
    };
    if el.props.iter().any(|p| p.name == name) {
        return Err(format!(
            "malformed PLY header: property {name} twice in {}",
            el.name
        ));
    }
    el.props.push(Prop {
        name: name.to_string(),
        kind,
    });
    Ok(())
}

/// Elements whose columns the strand reader needs; others are parsed and dropped.
const KEPT: [&str; 3] = ["vertex", "strand", "edge"];

fn read_ply_body(b: &[u8], encoding: PlyEncoding, elements: &[Element]) -> Msg<Vec<Table>> {
    let mut tables = Vec::with_capacity(elements.len());
    match encoding {
        PlyEncoding::Ascii => {
            let mut toks = b
                .split(|c| c.is_ascii_whitespace())
                .filter(|t| !t.is_empty());
            // Each value is at least one character and one separator, which bounds the rows
            // before anything is allocated for them.
            let max_values = b.len() / 2 + 1;
            let mut values = 0usize;
            for el in elements {
                values = values.saturating_add(el.count.saturating_mul(el.props.len()));
                if values > max_values {
                    return Err(format!(
                        "element {} count {} exceeds the file size",
                        el.name, el.count
                    ));
                }
                let keep = KEPT.contains(&el.name.as_str());
                let mut cols = new_cols(el, keep);
                for row in 0..el.count {
                    for (pi, p) in el.props.iter().enumerate() {
                        let mut next = |t: Scalar| -> Msg<f64> {
                            let tok = toks.next().ok_or_else(|| {
                                format!("truncated: element {} ends at row {row}", el.name)
                            })?;
                            std::str::from_utf8(tok)
                                .ok()
                                .and_then(|s| t.parse_ascii(s))
                                .ok_or_else(|| {
                                    format!(
                                        "bad {t:?} value {:?} in element {} row {row}",
                                        String::from_utf8_lossy(tok),
                                        el.name
                                    )
                                })
                        };
                        match p.kind {
                            PropKind::Scalar(t) => {
                                let v = next(t)?;
                                if let Some((_, c)) = &mut cols[pi] {
                                    c.push(v);
                                }
                            }
                            PropKind::List { count, item } => {
                                let n = next(count)?;
                                if n < 0.0 {
                                    return Err(format!("negative list length in {}", el.name));
                                }
                                for _ in 0..n as u64 {
                                    next(item)?;
                                }
                            }
                        }
                    }
                }
                tables.push(Table { cols });
            }
            if toks.next().is_some() {
                return Err("unexpected data after the last PLY element".into());
            }
        }
        PlyEncoding::BinaryLe | PlyEncoding::BinaryBe => {
            let mut r = Reader::new(b);
            r.big_endian = encoding == PlyEncoding::BinaryBe;
            for el in elements {
                let min_row: usize = el
                    .props
                    .iter()
                    .map(|p| match p.kind {
                        PropKind::Scalar(t) => t.size(),
                        PropKind::List { count, .. } => count.size(),
                    })
                    .sum();
                if el.count.saturating_mul(min_row) > r.remaining() {
                    return Err(format!(
                        "element {} count {} exceeds the file size",
                        el.name, el.count
                    ));
                }
                let keep = KEPT.contains(&el.name.as_str());
                let mut cols = new_cols(el, keep);
                for _ in 0..el.count {
                    for (pi, p) in el.props.iter().enumerate() {
                        match p.kind {
                            PropKind::Scalar(t) => {
                                let v = t.read_bin(&mut r)?;
                                if let Some((_, c)) = &mut cols[pi] {
                                    c.push(v);
                                }
                            }
                            PropKind::List { count, item } => {
                                let n = count.read_bin(&mut r)?;
                                if n < 0.0 {
                                    return Err(format!("negative list length in {}", el.name));
                                }
                                for _ in 0..n as u64 {
                                    item.read_bin(&mut r)?;
                                }
                            }
                        }
                    }
                }
                tables.push(Table { cols });
            }
            if r.remaining() != 0 {
                return Err(format!(
                    "{} unexpected bytes after the last PLY element",
                    r.remaining()
                ));
            }
        }
    }
    Ok(tables)
}

fn new_cols(el: &Element, keep: bool) -> Vec<Option<(Scalar, Vec<f64>)>> {
    el.props
        .iter()
        .map(|p| match p.kind {
            PropKind::Scalar(t) if keep => Some((t, Vec::with_capacity(el.count))),
            _ => None,
        })
        .collect()
}

/// An integer vertex index stored in a PLY column, checked against the vertex count.
fn ply_index(v: f64, nv: usize, what: &str) -> Msg<usize> {
    if v.fract() == 0.0 && v >= 0.0 && v < nv as f64 {
        Ok(v as usize)
    } else {
        Err(format!("{what} refers to vertex {v}, outside 0..{nv}"))
    }
}

const NOT_STRANDS: &str = "PLY has neither a strand nor an edge element (a mesh, not strands?)";

pub(super) fn decode_ply(b: &[u8]) -> Msg<StrandSet> {
    let (encoding, elements, body) = parse_ply_header(b)?;
    let find = |name: &str| elements.iter().position(|e| e.name == name);
    let vi = find("vertex").ok_or("PLY has no vertex element")?;
    let (si, ei) = (find("strand"), find("edge"));
    if si.is_none() && ei.is_none() {
        // Refuse before reading the body: a mesh (faces) is not a strand file.
        return Err(NOT_STRANDS.into());
    }
    let tables = read_ply_body(&b[body..], encoding, &elements)?;
    let (vel, vt) = (&elements[vi], &tables[vi]);
    let nv = vel.count;
    let xyz = ["x", "y", "z"].map(|n| vt.col(vel, n));
    let [Some((_, x)), Some((_, y)), Some((_, z))] = xyz else {
        return Err("PLY vertex element lacks scalar x, y, z".into());
    };
    let points: Vec<[f32; 3]> = (0..nv)
        .map(|i| [x[i] as f32, y[i] as f32, z[i] as f32])
        .collect();
    let rgb = |names: [&str; 3]| -> Option<Vec<[f32; 3]>> {
        let [Some(r), Some(g), Some(b)] = names.map(|n| vt.col(vel, n)) else {
            return None;
        };
        let ch = |(t, v): (Scalar, &[f64]), i: usize| (v[i] / t.max()) as f32;
        Some((0..nv).map(|i| [ch(r, i), ch(g, i), ch(b, i)]).collect())
    };
    let colors = rgb(["red", "green", "blue"])
        .or_else(|| rgb(["diffuse_red", "diffuse_green", "diffuse_blue"]));
    let scalar = |name: &str| {
        vt.col(vel, name)
            .map(|(_, v)| v.iter().map(|&x| x as f32).collect())
    };
    let thickness: Option<Vec<f32>> = scalar("thickness");
    let transparency: Option<Vec<f32>> = scalar("transparency");

    let edges = |ei: usize| -> Msg<Vec<(usize, usize)>> {
        let (el, t) = (&elements[ei], &tables[ei]);
        let (a, b) = match (t.col(el, "vertex1"), t.col(el, "vertex2")) {
            (Some(a), Some(b)) => (a.1, b.1),
            _ => return Err("PLY edge element lacks vertex1, vertex2".into()),
        };
        (0..el.count)
            .map(|i| {
                Ok((
                    ply_index(a[i], nv, "an edge")?,
                    ply_index(b[i], nv, "an edge")?,
                ))
            })
            .collect()
    };

    let set = if let Some(si) = si {
        let (sel, st) = (&elements[si], &tables[si]);
        let (_, nsegs) = st
            .col(sel, "nsegs")
            .ok_or("PLY strand element lacks scalar nsegs")?;
        let mut counts = Vec::with_capacity(nsegs.len());
        for (i, &n) in nsegs.iter().enumerate() {
            if n.fract() != 0.0 || !(0.0..u32::MAX as f64).contains(&n) {
                return Err(format!("strand {i} has nsegs {n}"));
            }
            counts.push(n as u32 + 1);
        }
        let total: u64 = counts.iter().map(|&c| u64::from(c)).sum();
        if total != nv as u64 {
            return Err(format!(
                "strand nsegs give {total} vertices but the vertex element has {nv}"
            ));
        }
        if let Some(ei) = ei {
            // Two descriptions of the same strands must agree, or the file is not what it
            // claims; compare as sets so edge order does not matter.
            let mut got = edges(ei)?;
            let mut want = Vec::with_capacity(got.len());
            let mut start = 0usize;
            for &c in &counts {
                want.extend((start..start + c as usize - 1).map(|v| (v, v + 1)));
                start += c as usize;
            }
            got.sort_unstable();
            if got != want {
                return Err("PLY edges do not match the strand nsegs".into());
            }
        }
        StrandSet {
            points,
            counts,
            thickness,
            transparency,
            colors,
        }
    } else if let Some(ei) = ei {
        let (order, counts) = chain_edges(nv, &edges(ei)?)?;
        let gather = |v: Vec<f32>| order.iter().map(|&i| v[i]).collect();
        StrandSet {
            points: order.iter().map(|&i| points[i]).collect(),
            counts,
            thickness: thickness.map(gather),
            transparency: transparency.map(gather),
            colors: colors.map(|c| order.iter().map(|&i| c[i]).collect()),
        }
    } else {
        return Err(NOT_STRANDS.into());
    };
    Ok(set)
}

/// Orders vertices into polylines from directed edges: returns the vertex order (roots in
/// ascending index, each followed along its edges) and the vertices per strand. A vertex on
/// no edge is a 1-vertex strand; branches and cycles are errors.
fn chain_edges(nv: usize, edges: &[(usize, usize)]) -> Msg<(Vec<usize>, Vec<u32>)> {
    let mut next = vec![usize::MAX; nv];
    let mut has_prev = vec![false; nv];
    for &(a, b) in edges {
        if a == b {
            return Err(format!("edge from vertex {a} to itself"));
        }
        if next[a] != usize::MAX {
            return Err(format!("vertex {a} starts two edges (branching strand)"));
        }
        if has_prev[b] {
            return Err(format!("vertex {b} ends two edges (strands merge)"));
        }
        next[a] = b;
        has_prev[b] = true;
    }
    let mut order = Vec::with_capacity(nv);
    let mut counts = Vec::new();
    for root in (0..nv).filter(|&v| !has_prev[v]) {
        let start = order.len();
        let mut v = root;
        loop {
            order.push(v);
            v = next[v];
            if v == usize::MAX {
                break;
            }
        }
        counts.push((order.len() - start) as u32);
    }
    if order.len() != nv {
        return Err(format!(
            "PLY edges form a cycle: {} vertices are on no root-to-tip strand",
            nv - order.len()
        ));
    }
    Ok((order, counts))
}

/// Colour channel to uchar; clamped because PLY stores 0..255.
fn to_u8(c: f32) -> u8 {
    (c.clamp(0.0, 1.0) * 255.0).round() as u8
}

fn ply_header(s: &StrandSet, format: &str, strand_element: bool) -> Msg<String> {
    let nv = i32::try_from(s.points.len())
        .map_err(|_| "too many points for PLY int vertex indices".to_string())?;
    let ne = s.points.len() - s.counts.len();
    let mut h = format!("ply\nformat {format} 1.0\ncomment written by coif\nelement vertex {nv}\n");
    h += "property float x\nproperty float y\nproperty float z\n";
    if s.colors.is_some() {
        h += "property uchar red\nproperty uchar green\nproperty uchar blue\n";
    }
    if s.thickness.is_some() {
        h += "property float thickness\n";
    }
    if s.transparency.is_some() {
        h += "property float transparency\n";
    }
    if strand_element {
        let _ = write!(
            h,
            "element strand {}\nproperty ushort nsegs\n",
            s.counts.len()
        );
    }
    let _ = write!(
        h,
        "element edge {ne}\nproperty int vertex1\nproperty int vertex2\nend_header\n"
    );
    Ok(h)
}

/// Consecutive vertex pairs of every strand.
fn strand_edges(s: &StrandSet) -> impl Iterator<Item = (u32, u32)> + '_ {
    let mut start = 0u32;
    s.counts.iter().flat_map(move |&c| {
        let first = start;
        start += c;
        (first..first + c - 1).map(|v| (v, v + 1))
    })
}

pub(super) fn encode_ply_binary(s: &StrandSet) -> Msg<Vec<u8>> {
    let mut out = ply_header(s, "binary_little_endian", false)?.into_bytes();
    for i in 0..s.points.len() {
        for x in s.points[i] {
            out.extend_from_slice(&x.to_le_bytes());
        }
        if let Some(c) = &s.colors {
            out.extend(c[i].map(to_u8));
        }
        for a in [&s.thickness, &s.transparency].into_iter().flatten() {
            out.extend_from_slice(&a[i].to_le_bytes());
        }
    }
    for (a, b) in strand_edges(s) {
        out.extend_from_slice(&(a as i32).to_le_bytes());
        out.extend_from_slice(&(b as i32).to_le_bytes());
    }
    Ok(out)
}

pub(super) fn encode_ply_ascii(s: &StrandSet) -> Msg<Vec<u8>> {
    if let Some(i) = s.counts.iter().position(|&c| c > 65536) {
        return Err(format!(
            "strand {i} has {} vertices; the PLY strand element stores nsegs as ushort",
            s.counts[i]
        ));
    }
    let mut t = ply_header(s, "ascii", true)?;
    // `{}` prints the shortest decimal that reads back to the same f32, never an exponent.
    for i in 0..s.points.len() {
        let [x, y, z] = s.points[i];
        let _ = write!(t, "{x} {y} {z}");
        if let Some(c) = &s.colors {
            let [r, g, b] = c[i].map(to_u8);
            let _ = write!(t, " {r} {g} {b}");
        }
        for a in [&s.thickness, &s.transparency].into_iter().flatten() {
            let _ = write!(t, " {}", a[i]);
        }
        t.push('\n');
    }
    for &c in &s.counts {
        let _ = writeln!(t, "{}", c - 1);
    }
    for (a, b) in strand_edges(s) {
        let _ = writeln!(t, "{a} {b}");
    }
    Ok(t.into_bytes())
}
