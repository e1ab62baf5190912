//! Strand files: cyHair `.hair`, USC-HairSalon `.data`, PLY (ascii and
//! binary), OBJ polylines and USD ascii (`.usda`, BasisCurves).
//!
//! Every decoder works on a byte slice with bounds-checked reads, so a truncated or hostile
//! file is an [`Error::BadFile`] naming it, never a panic, and no array is allocated larger
//! than the file could hold. Every encoder validates the set first and writes through
//! [`write_atomic`], so a failed write leaves no half file behind.

mod data;
mod hair;
mod obj;
mod ply;
mod usda;

use crate::error::{Error, Result};
use crate::hair::strands::StrandSet;
use crate::io::write_atomic;
use data::{decode_data, encode_data};
use hair::{decode_hair, encode_hair};
use obj::{decode_obj, encode_obj};
use ply::{decode_ply, encode_ply_ascii, encode_ply_binary};
use std::path::Path;
use usda::{encode_usda, encode_usda_animated};

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

/// Reads a `.hair`, `.data`, `.ply` or `.obj` strand file: the format by extension, else
/// (a pipe such as `/dev/stdin` has none) by content, see [`sniff`]. Read once, so a pipe
/// works.
pub fn read(path: &Path) -> Result<StrandSet> {
    let by_ext = Format::from_path(path);
    let bytes = std::fs::read(path).map_err(|e| Error::io(path, e))?;
    match by_ext {
        Ok(format) => decode(&bytes, format, path),
        Err(_) => sniff(&bytes, path),
    }
}

/// Decodes a strand file whose name does not give its format: `.hair` by its `HAIR` magic,
/// `.ply` by its `ply` header line, `.obj` when it is text whose first statement is an OBJ
/// one; anything else is tried as `.data`, which has no magic but a strict layout.
pub fn sniff(bytes: &[u8], path: &Path) -> Result<StrandSet> {
    if bytes.starts_with(b"HAIR") {
        return decode(bytes, Format::Hair, path);
    }
    if bytes.starts_with(b"ply\n") || bytes.starts_with(b"ply\r\n") {
        return decode(bytes, Format::Ply, path);
    }
    if let Ok(text) = std::str::from_utf8(bytes) {
        let first = text
            .lines()
            .map(str::trim)
            .find(|l| !l.is_empty() && !l.starts_with('#'));
        let obj = ["v", "l", "o", "g", "vn", "vt", "mtllib", "usemtl", "s"];
        if first.is_some_and(|l| obj.contains(&l.split_ascii_whitespace().next().unwrap_or(""))) {
            return decode(bytes, Format::Obj, path);
        }
    }
    decode_data(bytes)
        .and_then(|s| s.check().map(|()| s))
        .map_err(|msg| {
            Error::bad_file(
                path,
                format!(
                    "cannot tell the strand format: the name has no .hair, .data, .ply or .obj \
                 extension and the content is not .hair (HAIR magic), .ply (ply header) or \
                 .obj text; read as .data (which has no magic): {msg}"
                ),
            )
        })
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

/// Writes a sequence (same strands in every frame) as an animated USD stage, atomically; see
/// `usda::encode_usda_animated`. `head` holds one rigid transform per frame (row-major
/// rotation, then translation).
pub fn write_usda_animated(
    path: &Path,
    frames: &[StrandSet],
    head: &[[f32; 12]],
    fps: f32,
    opts: &UsdOptions,
) -> Result<()> {
    let bytes =
        encode_usda_animated(frames, head, fps, opts).map_err(|msg| Error::bad_file(path, msg))?;
    write_atomic(path, &bytes)
}
