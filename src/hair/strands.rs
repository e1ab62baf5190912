//! Strand hair models and their files: cyHair `.hair`, USC-HairSalon `.data`, PLY (ascii and
//! binary), OBJ polylines and USD ascii (`.usda`, BasisCurves).
//!
//! Every decoder works on a byte slice with bounds-checked reads, so a truncated or hostile
//! file is an [`Error::BadFile`] naming it, never a panic, and no array is allocated larger
//! than the file could hold. Every encoder validates the set first and writes through
//! [`write_atomic`], so a failed write leaves no half file behind.

use crate::error::{Error, Result};
use crate::io::write_atomic;
use std::fmt::Write as _;
use std::path::Path;

/// A strand model: strands are polylines root→tip; per-vertex optional attributes.
#[derive(Debug, Clone, PartialEq, Default)]
pub struct StrandSet {
    /// All vertices, strand after strand.
    pub points: Vec<[f32; 3]>,
    /// Vertices per strand (each >= 1; a 1-vertex strand is an empty root).
    pub counts: Vec<u32>,
    /// Per vertex, in the file's length unit (USD `widths`, i.e. a diameter).
    pub thickness: Option<Vec<f32>>,
    /// Per vertex, 0 opaque .. 1 fully transparent (cyHair's convention).
    pub transparency: Option<Vec<f32>>,
    /// Per vertex, linear 0..1.
    pub colors: Option<Vec<[f32; 3]>>,
}

impl StrandSet {
    /// A set with points and counts only.
    pub fn new(points: Vec<[f32; 3]>, counts: Vec<u32>) -> Self {
        StrandSet {
            points,
            counts,
            ..Default::default()
        }
    }

    /// Number of strands.
    pub fn len(&self) -> usize {
        self.counts.len()
    }

    pub fn is_empty(&self) -> bool {
        self.counts.is_empty()
    }

    /// The vertices of strand `i`. O(i): use [`StrandSet::strands`] to visit them all.
    ///
    /// # Panics
    /// If `i` is out of range or the counts exceed the points (see [`StrandSet::validate`]).
    pub fn strand(&self, i: usize) -> &[[f32; 3]] {
        let start: usize = self.counts[..i].iter().map(|&c| c as usize).sum();
        &self.points[start..start + self.counts[i] as usize]
    }

    /// Iterates the strands in order. Stops early if the counts exceed the points.
    pub fn strands(&self) -> impl Iterator<Item = &[[f32; 3]]> + '_ {
        let mut start = 0usize;
        self.counts.iter().map_while(move |&c| {
            let s = self.points.get(start..start + c as usize)?;
            start += c as usize;
            Some(s)
        })
    }

    /// Checks that the set is usable: at least one strand, every count >= 1, counts summing
    /// to the number of points, per-vertex attributes of that length, all values finite.
    pub fn validate(&self) -> Result<()> {
        self.check().map_err(Error::Invalid)
    }

    /// [`StrandSet::validate`] with a bare message, so readers and writers can name their file.
    fn check(&self) -> std::result::Result<(), String> {
        if self.counts.is_empty() {
            return Err("zero strands".into());
        }
        let mut total = 0u64;
        for (i, &c) in self.counts.iter().enumerate() {
            if c == 0 {
                return Err(format!("strand {i} has no vertices"));
            }
            total += u64::from(c);
        }
        if total != self.points.len() as u64 {
            return Err(format!(
                "strand vertex counts sum to {total} but there are {} points",
                self.points.len()
            ));
        }
        let n = self.points.len();
        if let Some(i) = self.points.iter().position(|p| !finite3(p)) {
            return Err(format!("point {i} is not finite: {:?}", self.points[i]));
        }
        fn attr<T>(
            name: &str,
            v: &Option<Vec<T>>,
            n: usize,
            ok: impl Fn(&T) -> bool,
        ) -> std::result::Result<(), String> {
            let Some(v) = v else { return Ok(()) };
            if v.len() != n {
                return Err(format!("{name} has {} values for {n} points", v.len()));
            }
            match v.iter().position(|x| !ok(x)) {
                Some(i) => Err(format!("{name} of point {i} is not finite")),
                None => Ok(()),
            }
        }
        attr("thickness", &self.thickness, n, |x| x.is_finite())?;
        attr("transparency", &self.transparency, n, |x| x.is_finite())?;
        attr("colors", &self.colors, n, finite3)
    }

    /// Axis-aligned bounds of the points as (min, max); zeros for a set without points.
    pub fn bounds(&self) -> ([f32; 3], [f32; 3]) {
        if self.points.is_empty() {
            return ([0.0; 3], [0.0; 3]);
        }
        let mut lo = [f32::INFINITY; 3];
        let mut hi = [f32::NEG_INFINITY; 3];
        for p in &self.points {
            for k in 0..3 {
                lo[k] = lo[k].min(p[k]);
                hi[k] = hi[k].max(p[k]);
            }
        }
        (lo, hi)
    }
}

fn finite3(p: &[f32; 3]) -> bool {
    p.iter().all(|x| x.is_finite())
}

/// The strand file formats, chosen by extension.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Format {
    Hair,
    Data,
    Ply,
    Obj,
    Usda,
}

impl Format {
    /// The format for a path's extension (case-insensitive).
    pub fn from_path(path: &Path) -> Result<Format> {
        let ext = path
            .extension()
            .and_then(|e| e.to_str())
            .map(|e| e.to_ascii_lowercase());
        match ext.as_deref() {
            Some("hair") => Ok(Format::Hair),
            Some("data") => Ok(Format::Data),
            Some("ply") => Ok(Format::Ply),
            Some("obj") => Ok(Format::Obj),
            Some("usda") => Ok(Format::Usda),
            _ => Err(Error::Invalid(format!(
                "{}: unknown strand format; expected .hair, .data, .ply, .obj or .usda",
                path.display()
            ))),
        }
    }

    pub fn extension(self) -> &'static str {
        match self {
            Format::Hair => "hair",
            Format::Data => "data",
            Format::Ply => "ply",
            Format::Obj => "obj",
            Format::Usda => "usda",
        }
    }
}

/// Reads a `.hair`, `.data`, `.ply` or `.obj` strand file (format by extension).
pub fn read(path: &Path) -> Result<StrandSet> {
    let format = Format::from_path(path)?;
    let bytes = std::fs::read(path).map_err(|e| Error::io(path, e))?;
    decode(&bytes, format, path)
}

/// Decodes file bytes; `path` only names the file in errors. `.usda` is write-only.
pub fn decode(bytes: &[u8], format: Format, path: &Path) -> Result<StrandSet> {
    let set = match format {
        Format::Hair => decode_hair(bytes),
        Format::Data => decode_data(bytes),
        Format::Ply => decode_ply(bytes),
        Format::Obj => decode_obj(bytes),
        Format::Usda => {
            Err("reading .usda is not supported; use .hair, .data, .ply or .obj".into())
        }
    };
    set.and_then(|s| s.check().map(|()| s))
        .map_err(|msg| Error::bad_file(path, msg))
}

/// Writes `s` in the format of `path`'s extension, atomically. `.usda` gets
/// [`UsdOptions::default`], `.ply` the binary edge variant.
pub fn write(path: &Path, s: &StrandSet) -> Result<()> {
    let bytes = encode(s, Format::from_path(path)?, path)?;
    write_atomic(path, &bytes)
}

/// Encodes `s` as file bytes; `path` only names the file in errors.
pub fn encode(s: &StrandSet, format: Format, path: &Path) -> Result<Vec<u8>> {
    s.check()
        .and_then(|()| match format {
            Format::Hair => encode_hair(s),
            Format::Data => encode_data(s),
            Format::Ply => encode_ply_binary(s),
            Format::Obj => Ok(encode_obj(s)),
            Format::Usda => encode_usda(s, &UsdOptions::default()),
        })
        .map_err(|msg| Error::bad_file(path, msg))
}

/// Writes the ascii "vertex + strand(nsegs) + edge" PLY variant (as hairutil writes it).
pub fn write_ply_ascii(path: &Path, s: &StrandSet) -> Result<()> {
    let bytes = s
        .check()
        .and_then(|()| encode_ply_ascii(s))
        .map_err(|msg| Error::bad_file(path, msg))?;
    write_atomic(path, &bytes)
}

/// Which axis is up in a USD stage.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum UpAxis {
    Y,
    Z,
}

/// Stage and prim settings for `.usda` output.
#[derive(Debug, Clone, PartialEq)]
pub struct UsdOptions {
    /// Stage `metersPerUnit`; 0.001 because coif's strand data is in millimetre-like units.
    pub meters_per_unit: f64,
    pub up_axis: UpAxis,
    /// Curve width (diameter, scene units) when the set has no thickness.
    pub default_width: f32,
    /// Name of the root BasisCurves prim (and the stage's defaultPrim).
    pub prim_name: String,
}

impl Default for UsdOptions {
    fn default() -> Self {
        UsdOptions {
            meters_per_unit: 0.001,
            up_axis: UpAxis::Y,
            // Human hair is roughly 0.05-0.1 mm across.
            default_width: 0.07,
            prim_name: "hair".into(),
        }
    }
}

/// Writes `s` as a USD ascii stage holding one linear BasisCurves prim, atomically.
pub fn write_usda(path: &Path, s: &StrandSet, opts: &UsdOptions) -> Result<()> {
    let bytes = s
        .check()
        .and_then(|()| encode_usda(s, opts))
        .map_err(|msg| Error::bad_file(path, msg))?;
    write_atomic(path, &bytes)
}

type Msg<T> = std::result::Result<T, String>;

/// Bounds-checked little/big-endian reader over a byte slice.
struct Reader<'a> {
    b: &'a [u8],
    pos: usize,
    big_endian: bool,
}

impl<'a> Reader<'a> {
    fn new(b: &'a [u8]) -> Self {
        Reader {
            b,
            pos: 0,
            big_endian: false,
        }
    }

    fn remaining(&self) -> usize {
        self.b.len() - self.pos
    }

    fn take<const N: usize>(&mut self) -> Msg<[u8; N]> {
        if self.remaining() < N {
            return Err(format!(
                "truncated: needs {N} more bytes at offset {}, file has {}",
                self.pos,
                self.b.len()
            ));
        }
        let mut out = [0u8; N];
        out.copy_from_slice(&self.b[self.pos..self.pos + N]);
        self.pos += N;
        if self.big_endian {
            out.reverse();
        }
        Ok(out)
    }

    fn u16(&mut self) -> Msg<u16> {
        self.take().map(u16::from_le_bytes)
    }
    fn u32(&mut self) -> Msg<u32> {
        self.take().map(u32::from_le_bytes)
    }
    fn i32(&mut self) -> Msg<i32> {
        self.take().map(i32::from_le_bytes)
    }
    fn f32(&mut self) -> Msg<f32> {
        self.take().map(f32::from_le_bytes)
    }
    fn vec3(&mut self) -> Msg<[f32; 3]> {
        Ok([self.f32()?, self.f32()?, self.f32()?])
    }
}

/// True when every value has the same bits, so it can be stored once.
fn uniform(v: &[f32]) -> bool {
    v.iter().all(|x| x.to_bits() == v[0].to_bits())
}

// ---------------------------------------------------------------- cyHair .hair

const HAIR_SEGMENTS: u32 = 1;
const HAIR_POINTS: u32 = 2;
const HAIR_THICKNESS: u32 = 4;
const HAIR_TRANSPARENCY: u32 = 8;
const HAIR_COLORS: u32 = 16;
const HAIR_HEADER: usize = 128;

fn decode_hair(b: &[u8]) -> Msg<StrandSet> {
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

fn encode_hair(s: &StrandSet) -> Msg<Vec<u8>> {
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

// ---------------------------------------------------------------- USC-HairSalon .data

fn decode_data(b: &[u8]) -> Msg<StrandSet> {
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

fn encode_data(s: &StrandSet) -> Msg<Vec<u8>> {
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

// ---------------------------------------------------------------- PLY

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

fn decode_ply(b: &[u8]) -> Msg<StrandSet> {
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

fn encode_ply_binary(s: &StrandSet) -> Msg<Vec<u8>> {
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

fn encode_ply_ascii(s: &StrandSet) -> Msg<Vec<u8>> {
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

// ---------------------------------------------------------------- OBJ

fn decode_obj(b: &[u8]) -> Msg<StrandSet> {
    let text = std::str::from_utf8(b).map_err(|_| "not a text OBJ file (invalid UTF-8)")?;
    let mut verts: Vec<[f32; 3]> = Vec::new();
    let mut vcols: Vec<[f32; 3]> = Vec::new();
    let mut all_colored = true;
    let mut lines: Vec<Vec<usize>> = Vec::new();
    for (ln, line) in text.lines().enumerate() {
        let mut toks = line.split_ascii_whitespace();
        let bad = |what: &str| format!("line {}: {what}: {line:?}", ln + 1);
        match toks.next() {
            Some("v") => {
                let vals = toks
                    .map(|t| t.parse::<f32>())
                    .collect::<std::result::Result<Vec<f32>, _>>()
                    .map_err(|_| bad("bad vertex"))?;
                match vals.len() {
                    3 | 4 => all_colored = false,
                    // "v x y z r g b" is the common vertex-colour extension (MeshLab, Blender).
                    6 => vcols.push([vals[3], vals[4], vals[5]]),
                    _ => return Err(bad("a vertex needs 3, 4 or 6 numbers")),
                }
                verts.push([vals[0], vals[1], vals[2]]);
            }
            Some("l") => {
                let mut idx = Vec::new();
                for t in toks {
                    // "l v/vt" also occurs; only the vertex index matters here.
                    let v: i64 = t
                        .split('/')
                        .next()
                        .and_then(|s| s.parse().ok())
                        .ok_or_else(|| bad("bad index"))?;
                    // Negative indices count back from the vertices seen so far.
                    let abs = if v < 0 { verts.len() as i64 + v } else { v - 1 };
                    if abs < 0 {
                        return Err(bad("index out of range"));
                    }
                    idx.push(abs as usize);
                }
                if idx.is_empty() {
                    return Err(bad("polyline without vertices"));
                }
                lines.push(idx);
            }
            _ => {}
        }
    }
    if lines.is_empty() {
        return Err("no polylines (\"l\" lines) in OBJ".into());
    }
    let n = verts.len();
    let mut points = Vec::new();
    let mut colors = Vec::new();
    let mut counts = Vec::with_capacity(lines.len());
    let colored = all_colored && !vcols.is_empty();
    for l in &lines {
        for &i in l {
            let p = verts
                .get(i)
                .ok_or_else(|| format!("polyline index {} outside 1..={n}", i + 1))?;
            points.push(*p);
            if colored {
                colors.push(vcols[i]);
            }
        }
        counts.push(l.len() as u32);
    }
    let mut s = StrandSet::new(points, counts);
    s.colors = colored.then_some(colors);
    Ok(s)
}

fn encode_obj(s: &StrandSet) -> Vec<u8> {
    let mut t = format!(
        "# written by coif: {} strands, {} points\n",
        s.counts.len(),
        s.points.len()
    );
    for (i, [x, y, z]) in s.points.iter().enumerate() {
        let _ = write!(t, "v {x} {y} {z}");
        if let Some(c) = &s.colors {
            let [r, g, b] = c[i];
            let _ = write!(t, " {r} {g} {b}");
        }
        t.push('\n');
    }
    // A 1-vertex strand is written as "l i": kept so the strand count survives.
    let mut next = 1usize;
    for &c in &s.counts {
        t.push('l');
        for v in next..next + c as usize {
            let _ = write!(t, " {v}");
        }
        t.push('\n');
        next += c as usize;
    }
    t.into_bytes()
}

// ---------------------------------------------------------------- USD ascii

fn encode_usda(s: &StrandSet, o: &UsdOptions) -> Msg<Vec<u8>> {
    let name = &o.prim_name;
    let valid_name = name
        .chars()
        .next()
        .is_some_and(|c| c.is_ascii_alphabetic() || c == '_')
        && name.chars().all(|c| c.is_ascii_alphanumeric() || c == '_');
    if !valid_name {
        return Err(format!("USD prim name {name:?} is not an identifier"));
    }
    if !(o.meters_per_unit.is_finite() && o.meters_per_unit > 0.0) {
        return Err(format!(
            "metersPerUnit {} must be positive",
            o.meters_per_unit
        ));
    }
    if !(o.default_width.is_finite() && o.default_width >= 0.0) {
        return Err(format!("default width {} must be >= 0", o.default_width));
    }
    let up = match o.up_axis {
        UpAxis::Y => "Y",
        UpAxis::Z => "Z",
    };
    let mut t = String::with_capacity(64 + s.points.len() * 48);
    let _ = write!(
        t,
        "#usda 1.0\n(\n    defaultPrim = \"{name}\"\n    doc = \"written by coif: {} strands, {} points\"\n    metersPerUnit = {}\n    upAxis = \"{up}\"\n)\n\n",
        s.counts.len(),
        s.points.len(),
        o.meters_per_unit
    );
    let _ = write!(
        t,
        "def BasisCurves \"{name}\"\n{{\n    uniform token type = \"linear\"\n    uniform token wrap = \"nonperiodic\"\n"
    );
    let list = |t: &mut String, items: &mut dyn Iterator<Item = String>| {
        t.push('[');
        for (i, it) in items.enumerate() {
            if i > 0 {
                t.push_str(", ");
            }
            t.push_str(&it);
        }
        t.push(']');
    };
    let vec3 = |[x, y, z]: [f32; 3]| format!("({x}, {y}, {z})");
    t.push_str("    int[] curveVertexCounts = ");
    list(&mut t, &mut s.counts.iter().map(|c| c.to_string()));
    t.push_str("\n    point3f[] points = ");
    list(&mut t, &mut s.points.iter().map(|&p| vec3(p)));
    t.push_str("\n    float[] widths = ");
    let max_width = match &s.thickness {
        Some(w) => {
            list(&mut t, &mut w.iter().map(|x| x.to_string()));
            t.push_str(" (\n        interpolation = \"vertex\"\n    )\n");
            w.iter().fold(0.0f32, |m, &x| m.max(x))
        }
        None => {
            let _ = write!(
                t,
                "[{}] (\n        interpolation = \"constant\"\n    )\n",
                o.default_width
            );
            o.default_width
        }
    };
    // UsdGeom's curve extent pads the points by half the widest width.
    let (lo, hi) = s.bounds();
    let pad = max_width / 2.0;
    let _ = writeln!(
        t,
        "    float3[] extent = [{}, {}]",
        vec3(lo.map(|v| v - pad)),
        vec3(hi.map(|v| v + pad))
    );
    if let Some(c) = &s.colors {
        t.push_str("    color3f[] primvars:displayColor = ");
        list(&mut t, &mut c.iter().map(|&p| vec3(p)));
        t.push_str(" (\n        interpolation = \"vertex\"\n    )\n");
    }
    if let Some(tr) = &s.transparency {
        t.push_str("    float[] primvars:displayOpacity = ");
        list(&mut t, &mut tr.iter().map(|&x| (1.0 - x).to_string()));
        t.push_str(" (\n        interpolation = \"vertex\"\n    )\n");
    }
    t.push_str("}\n");
    Ok(t.into_bytes())
}
