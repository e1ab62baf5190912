//! `hair.czs`: the sketch's codes bit-packed, with its length and a CRC-32. Version 3 range
//! codes the curves ([`rc`], adaptive contexts), version 4 with richer contexts, version 5
//! the colour map and the region too, and the curves sorted by start with their paint
//! order; versions 1 and 2 (fixed-width fields) are still read, as are 3 and 4.

use super::czs_rc::{curve_ledger, rc_curves, un_rc_curves};
use super::*;

struct BitWriter {
    bytes: Vec<u8>,
    bits: usize,
}

impl BitWriter {
    fn new() -> Self {
        BitWriter {
            bytes: Vec::new(),
            bits: 0,
        }
    }

    /// The low `n` bits of `v`, most significant first.
    fn put(&mut self, v: u64, n: u32) {
        for i in (0..n).rev() {
            if self.bits.is_multiple_of(8) {
                self.bytes.push(0);
            }
            if (v >> i) & 1 == 1 {
                let last = self.bytes.len() - 1;
                self.bytes[last] |= 0x80 >> (self.bits % 8);
            }
            self.bits += 1;
        }
    }

    /// Elias gamma code of `v` ≥ 1.
    fn gamma(&mut self, v: u64) {
        debug_assert!(v >= 1);
        let n = 64 - v.leading_zeros();
        self.put(0, n - 1);
        self.put(v, n);
    }
}

struct BitReader<'a> {
    data: &'a [u8],
    pos: usize,
}

impl BitReader<'_> {
    fn left(&self) -> usize {
        self.data.len() * 8 - self.pos
    }

    fn get(&mut self, n: u32, what: &str) -> std::result::Result<u64, String> {
        if self.left() < n as usize {
            return Err(format!("corrupted: the data ends inside {what}"));
        }
        let mut v = 0u64;
        for _ in 0..n {
            let bit = (self.data[self.pos / 8] >> (7 - self.pos % 8)) & 1;
            v = (v << 1) | bit as u64;
            self.pos += 1;
        }
        Ok(v)
    }

    fn gamma(&mut self, what: &str) -> std::result::Result<u64, String> {
        let mut zeros = 0;
        while self.get(1, what)? == 0 {
            zeros += 1;
            if zeros > 40 {
                return Err(format!("corrupted: {what} is out of range"));
            }
        }
        Ok((1u64 << zeros) | self.get(zeros, what)?)
    }
}

/// Bits needed to store values 0..=n.
pub(super) fn bits_for(n: u32) -> u32 {
    32 - n.leading_zeros()
}

fn crc32(data: &[u8]) -> u32 {
    let mut crc = !0u32;
    for &b in data {
        crc ^= b as u32;
        for _ in 0..8 {
            crc = if crc & 1 == 1 {
                (crc >> 1) ^ 0xEDB8_8320
            } else {
                crc >> 1
            };
        }
    }
    !crc
}

fn leb128(mut v: u64) -> Vec<u8> {
    let mut out = Vec::new();
    loop {
        let b = (v & 0x7f) as u8;
        v >>= 7;
        if v == 0 {
            out.push(b);
            return out;
        }
        out.push(b | 0x80);
    }
}

/// Signed to unsigned, small magnitudes small: 0, −1, 1, −2, ... → 0, 1, 2, 3, ...
pub(super) fn zigzag(v: i64) -> u64 {
    ((v << 1) ^ (v >> 63)) as u64
}

pub(super) fn unzigzag(u: u64) -> i64 {
    (u >> 1) as i64 ^ -((u & 1) as i64)
}

/// The header's two flags: whether any side carries a refinement, whether any free side's
/// direction is undecided.
fn flags(c: &Codes) -> (bool, bool) {
    let refine = c
        .curves
        .iter()
        .flat_map(|cv| &cv.prims)
        .any(|p| p.side.iter().any(|s| s.1 != 8));
    let undecided = c
        .curves
        .iter()
        .any(|cv| free_labels(cv.kind).iter().any(|&i| cv.dirs[i] == 0));
    (refine, undecided)
}

/// Packs the payload; returns it and the bit counts of (header, curves, shading, colour,
/// region). `measure`: split the range-coded tail's bits between its parts (two more
/// encodings of it; without, the tail counts as curves).
fn pack(c: &Codes, version: u8, measure: bool) -> (Vec<u8>, [usize; 5]) {
    let mut w = BitWriter::new();
    w.gamma(c.width as u64 + 1);
    w.gamma(c.height as u64 + 1);
    let sb = 64 - c.seed.leading_zeros();
    w.put(sb as u64, 7);
    w.put(c.seed, sb);
    let (refine, undecided) = flags(c);
    w.put(refine as u64, 1);
    w.put(undecided as u64, 1);
    for &r in &c.rho_off {
        w.put(r as u64, 8);
    }
    if version >= 6 {
        w.put(c.along_across as u64, 8);
    }
    let header = w.bits;

    let curves = if version >= 3 {
        0
    } else {
        put_curves_v2(&mut w, c, refine, undecided);
        w.bits - header
    };

    let (bx, by) = (
        bits_for(blocks(c.width).saturating_sub(1)),
        bits_for(blocks(c.height).saturating_sub(1)),
    );
    w.put(c.mean as u64, 10);
    w.gamma(c.bases.len() as u64 + 1);
    for b in &c.bases {
        w.put(b.x as u64, bx);
        w.put(b.y as u64, by);
        w.put(b.theta as u64, 3);
        w.put(b.sx as u64, 3);
        w.put(b.sy as u64, 3);
        w.put(b.amp as u8 as u64, 8);
    }
    let shading = w.bits - header - curves;

    // The colour map (before version 5; then it is range coded with the curves).
    for k in c.colour.k.iter().filter(|_| version < 5) {
        w.put(k[0] as u64, 6);
        w.put(k[1] as u64, 6);
    }
    let colour = w.bits - header - curves - shading;

    // Region (before version 5; then it is range coded with the curves): polygons, each a
    // vertex count, its first vertex and the steps to the next ones (zigzag, Elias-γ: short
    // steps are short).
    let (xb, yb) = (bits_for(c.width), bits_for(c.height));
    let region = if version >= 5 { &[][..] } else { &c.region[..] };
    if version < 5 {
        w.gamma(c.region.len() as u64 + 1);
    }
    for poly in region {
        w.gamma(poly.len() as u64 - 2);
        w.put(poly[0][0] as u64, xb);
        w.put(poly[0][1] as u64, yb);
        for pair in poly.windows(2) {
            for (a, b) in pair[0].iter().zip(&pair[1]) {
                w.gamma(zigzag(*b as i64 - *a as i64) + 1);
            }
        }
    }
    let region = w.bits - header - curves - shading - colour;
    if version < 3 {
        return (w.bytes, [header, curves, shading, colour, region]);
    }
    // Versions 3 to 5: the curves last (from 5, the region and the curves), range coded
    // from the next whole byte on.
    let (coded, [rc_colour, rc_region]) = rc_curves(c, refine, undecided, version, measure);
    let pad = w.bytes.len() * 8 - w.bits;
    let mut bytes = w.bytes;
    bytes.extend(&coded);
    let rc_curves = (coded.len() - rc_region - rc_colour) * 8 + pad;
    (
        bytes,
        [
            header,
            rc_curves,
            shading,
            colour + rc_colour * 8,
            region + rc_region * 8,
        ],
    )
}

/// The curve section of versions 1 and 2: fixed-width fields.
fn put_curves_v2(w: &mut BitWriter, c: &Codes, refine: bool, undecided: bool) {
    let (xb, yb) = (bits_for(c.width), bits_for(c.height));
    w.gamma(c.curves.len() as u64 + 1);
    for cv in &c.curves {
        w.put(cv.kind.code() as u64, 3);
        for &i in free_labels(cv.kind) {
            let d = cv.dirs[i];
            if undecided {
                w.put(signed_code(d) as u64, 2);
            } else {
                w.put((d > 0) as u64, 1);
            }
        }
        w.gamma(cv.prims.len() as u64);
        w.put(cv.start[0] as u64, xb);
        w.put(cv.start[1] as u64, yb);
        w.put(cv.axis as u64, 5);
        let hair = cv.kind.hair_sides();
        for (k, p) in cv.prims.iter().enumerate() {
            if k > 0 {
                w.put(signed_code(p.turn) as u64, 2);
            }
            for (side, _) in p.side.iter().zip(hair).filter(|(_, h)| *h) {
                w.put(side.0 as u64, 2);
                if refine {
                    w.put(side.1 as u64, 4);
                }
            }
            w.put(p.rho as u64, 4);
        }
    }
}

fn assemble(c: &Codes, version: u8, measure: bool) -> (Vec<u8>, [usize; 5]) {
    let (payload, bits) = pack(c, version, measure);
    // The total length includes its own varint: find the fixed point.
    let mut total = 4 + payload.len() + 4 + 1;
    loop {
        let t = 4 + leb128(total as u64).len() + payload.len() + 4;
        if t == total {
            break;
        }
        total = t;
    }
    let mut out = Vec::with_capacity(total);
    out.extend_from_slice(MAGIC);
    out.push(version);
    out.extend(leb128(total as u64));
    out.extend(&payload);
    let crc = crc32(&out);
    out.extend(crc.to_le_bytes());
    (out, bits)
}

/// The `.czs` bytes of the quantised sketch.
pub fn to_czs(s: &Sketch) -> Vec<u8> {
    assemble(&codes(s), CZS_VERSION, false).0
}

/// Bytes per part of `s`'s `.czs`.
pub fn czs_sizes(s: &Sketch) -> CzsSizes {
    let c = codes(s);
    let (bytes, bits) = assemble(&c, CZS_VERSION, true);
    let (refine, undecided) = flags(&c);
    let fields = curve_ledger(&c, refine, undecided, CZS_VERSION)
        .into_iter()
        .map(|(name, b)| (name, (b / 8.0 * 10.0).round() / 10.0))
        .collect();
    let part = |b: usize| b.div_ceil(8);
    let (curves, shading, colour, region) =
        (part(bits[1]), part(bits[2]), part(bits[3]), part(bits[4]));
    CzsSizes {
        header: bytes.len() - curves - shading - colour - region,
        curves,
        shading,
        colour,
        region,
        total: bytes.len(),
        fields,
    }
}

fn unpack(data: &[u8], version: u8) -> std::result::Result<Codes, String> {
    let mut r = BitReader { data, pos: 0 };
    let dim = |r: &mut BitReader, what: &str| -> std::result::Result<u32, String> {
        let v = r.gamma(what)? - 1;
        if v == 0 || v > u32::MAX as u64 {
            return Err(format!("corrupted: the image {what} is {v}"));
        }
        Ok(v as u32)
    };
    let width = dim(&mut r, "width")?;
    let height = dim(&mut r, "height")?;
    let sb = r.get(7, "the seed")? as u32;
    if sb > 64 {
        return Err(format!("corrupted: a seed of {sb} bits"));
    }
    let seed = r.get(sb, "the seed")?;
    let refine = r.get(1, "the flags")? == 1;
    let undecided = r.get(1, "the flags")? == 1;
    let mut rho_off = [0u8; 5];
    for v in &mut rho_off {
        *v = r.get(8, "the contrast prior")? as u8;
    }
    let along_across = if version >= 6 {
        r.get(8, "the along/across ratio")? as u8
    } else {
        0
    };

    let (xb, yb) = (bits_for(width), bits_for(height));
    let mut curves = if version >= 3 {
        Vec::new()
    } else {
        get_curves_v2(&mut r, width, height, refine, undecided)?
    };

    let (wc, hc) = (blocks(width), blocks(height));
    let (bx, by) = (bits_for(wc - 1), bits_for(hc - 1));
    let mean = r.get(10, "the shading mean")? as u16;
    if mean > 1023 {
        return Err("corrupted: shading mean".into());
    }
    let n_bases = r.gamma("the base count")? - 1;
    let mut bases = Vec::new();
    for bi in 0..n_bases {
        let at = format!("shading base {bi}");
        let b = BaseCodes {
            x: r.get(bx, &at)? as u32,
            y: r.get(by, &at)? as u32,
            theta: r.get(3, &at)? as u8,
            sx: r.get(3, &at)? as u8,
            sy: r.get(3, &at)? as u8,
            amp: r.get(8, &at)? as u8 as i8,
        };
        if b.x >= wc || b.y >= hc {
            return Err(format!("corrupted: {at} lies outside the image"));
        }
        bases.push(b);
    }

    let mut k = Vec::new();
    for _ in (0..COLOUR_BINS).filter(|_| version < 5) {
        k.push([
            r.get(6, "the colour map")? as u8,
            r.get(6, "the colour map")? as u8,
        ]);
    }
    let mut region = Vec::new();
    if (2..5).contains(&version) {
        let n = r.gamma("the region")? - 1;
        for pi in 0..n {
            let at = format!("region polygon {pi}");
            let nv = r.gamma(&at)? + 2;
            if nv as usize > 8 * data.len() {
                return Err(format!("corrupted: {at} has {nv} vertices"));
            }
            let mut poly = vec![[r.get(xb, &at)? as u32, r.get(yb, &at)? as u32]];
            for _ in 1..nv {
                let last = *poly.last().expect("one vertex");
                let mut q = [0u32; 2];
                for a in 0..2 {
                    let v = last[a] as i64 + unzigzag(r.gamma(&at)? - 1);
                    if v < 0 || v > [width, height][a] as i64 {
                        return Err(format!("corrupted: {at} leaves the {width}x{height} image"));
                    }
                    q[a] = v as u32;
                }
                poly.push(q);
            }
            region.push(poly);
        }
    }
    if version >= 3 {
        let pad = (8 - r.pos % 8) % 8;
        if pad > 0 && r.get(pad as u32, "the padding")? != 0 {
            return Err("corrupted: the padding bits are not zero".into());
        }
        let tail = un_rc_curves(
            &data[r.pos / 8..],
            width,
            height,
            refine,
            undecided,
            version,
        )?;
        curves = tail.curves;
        if let Some(c) = tail.colour {
            k = c.k;
        }
        if let Some(rc_region) = tail.region {
            region = rc_region;
        }
    } else {
        if r.left() >= 8 {
            return Err(format!(
                "corrupted: {} bytes left over after the sketch",
                r.left() / 8
            ));
        }
        if r.left() > 0 && r.get(r.left() as u32, "the padding")? != 0 {
            return Err("corrupted: the padding bits are not zero".into());
        }
    }
    Ok(Codes {
        width,
        height,
        seed,
        curves,
        rho_off,
        mean,
        bases,
        colour: ColourCodes { k },
        region,
        along_across,
    })
}

/// The code of a label or turn (0, +1, −1 → 0, 1, 2) in every version.
pub(super) fn signed_code(d: i8) -> u32 {
    match d {
        0 => 0,
        1 => 1,
        _ => 2,
    }
}

/// [`signed_code`] read back; code 3 is damage, described by `what`.
pub(super) fn signed_of(
    code: u32,
    what: impl FnOnce() -> String,
) -> std::result::Result<i8, String> {
    match code {
        0 => Ok(0),
        1 => Ok(1),
        2 => Ok(-1),
        _ => Err(format!("corrupted: {}", what())),
    }
}

pub(super) fn kind_of(code: u8, at: &str) -> std::result::Result<Kind, String> {
    Kind::from_code(code).ok_or_else(|| format!("corrupted: {at} has kind code {code}"))
}

/// The labels a kind fixes (d outward, e shared) over those read.
pub(super) fn fixed_dirs(kind: Kind, dirs: [i8; 2]) -> [i8; 2] {
    match kind {
        Kind::Dividing => [1, 1],
        Kind::Stream => [dirs[0], dirs[0]],
        _ => dirs,
    }
}

/// A curve's start inside the image and its axis code on the lattice.
pub(super) fn check_placement(
    start: [u32; 2],
    axis: u8,
    width: u32,
    height: u32,
    at: &str,
) -> std::result::Result<(), String> {
    if start[0] > width || start[1] > height {
        return Err(format!(
            "corrupted: {at} starts at ({}, {}), outside the {width}x{height} image",
            start[0], start[1]
        ));
    }
    if axis as u32 >= AXIS_STEPS {
        return Err(format!("corrupted: {at} has axis code {axis}"));
    }
    Ok(())
}

/// The curve section of versions 1 and 2.
fn get_curves_v2(
    r: &mut BitReader,
    width: u32,
    height: u32,
    refine: bool,
    undecided: bool,
) -> std::result::Result<Vec<CurveCodes>, String> {
    let (xb, yb) = (bits_for(width), bits_for(height));
    let n_curves = r.gamma("the curve count")? - 1;
    let mut curves = Vec::new();
    for ci in 0..n_curves {
        let at = format!("curve {ci}");
        let kind = kind_of(r.get(3, &at)? as u8, &at)?;
        let mut dirs = [0i8; 2];
        for &i in free_labels(kind) {
            dirs[i] = if undecided {
                signed_of(r.get(2, &at)? as u32, || format!("{at} has label code 3"))?
            } else if r.get(1, &at)? == 1 {
                1
            } else {
                -1
            };
        }
        let dirs = fixed_dirs(kind, dirs);
        let n = r.gamma(&at)?;
        let start = [r.get(xb, &at)? as u32, r.get(yb, &at)? as u32];
        let axis = r.get(5, &at)? as u8;
        check_placement(start, axis, width, height, &at)?;
        let hair = kind.hair_sides();
        let mut prims = Vec::new();
        for k in 0..n {
            let turn = if k == 0 {
                0
            } else {
                signed_of(r.get(2, &at)? as u32, || {
                    format!("{at}, primitive {k} has turn code 3")
                })?
            };
            let mut side = [(0u8, 8u8); 2];
            for s in 0..2 {
                if hair[s] {
                    side[s].0 = r.get(2, &at)? as u8;
                    if refine {
                        side[s].1 = r.get(4, &at)? as u8;
                    }
                }
            }
            let rho = r.get(4, &at)? as u8;
            prims.push(PrimCodes {
                turn,
                side,
                rho,
                shift: SHIFT_ZERO,
            });
        }
        curves.push(CurveCodes {
            kind,
            dirs,
            start,
            axis,
            prims,
        });
    }
    Ok(curves)
}

/// Reads a `.czs` file's bytes; `path` names it in errors. The sketch is checked by
/// [`validate`].
pub fn from_czs(bytes: &[u8], path: &Path) -> Result<Sketch> {
    let bad = |m: String| Error::bad_file(path, m);
    if bytes.is_empty() {
        return Err(bad("empty file, not a .czs sketch".into()));
    }
    let n = bytes.len().min(3);
    if bytes[..n] != MAGIC[..n] {
        return Err(bad(
            "not a .czs sketch (it does not start with \"CZS\")".into()
        ));
    }
    if bytes.len() < 5 {
        return Err(bad(format!(
            "truncated: {} bytes, shorter than the header",
            bytes.len()
        )));
    }
    if bytes[3] == 0 || bytes[3] > CZS_VERSION {
        return Err(bad(format!(
            "unsupported .czs version {} (this build reads versions 1 to {CZS_VERSION})",
            bytes[3]
        )));
    }
    let mut total = 0u64;
    let mut at = 4;
    loop {
        let Some(&b) = bytes.get(at) else {
            return Err(bad(format!(
                "truncated: {} bytes, shorter than the header",
                bytes.len()
            )));
        };
        if at - 4 >= 5 {
            return Err(bad("corrupted: the length field is too long".into()));
        }
        total |= ((b & 0x7f) as u64) << (7 * (at - 4));
        at += 1;
        if b & 0x80 == 0 {
            break;
        }
    }
    if bytes.len() as u64 != total && bytes.len() >= at + 4 {
        // A complete file whose length field was damaged still checks out.
        let (body, tail) = bytes.split_at(bytes.len() - 4);
        if crc32(body).to_le_bytes() == tail {
            return Err(bad(format!(
                "corrupted: the length field says {total} bytes, the file has {}",
                bytes.len()
            )));
        }
    }
    if (bytes.len() as u64) < total {
        return Err(bad(format!(
            "truncated: {} of the {total} bytes its header announces",
            bytes.len()
        )));
    }
    if bytes.len() as u64 > total {
        return Err(bad(format!(
            "{} bytes after the end of the sketch (its header announces {total} bytes)",
            bytes.len() as u64 - total
        )));
    }
    if total < at as u64 + 4 {
        return Err(bad(format!("corrupted: a length of {total} bytes")));
    }
    let body = &bytes[..bytes.len() - 4];
    let stored = u32::from_le_bytes(bytes[bytes.len() - 4..].try_into().expect("4 bytes"));
    if crc32(body) != stored {
        return Err(bad("checksum mismatch: the file is corrupted".into()));
    }
    let c = unpack(&body[at..], bytes[3]).map_err(bad)?;
    let s = decode(&c);
    validate(&s, path)?;
    Ok(s)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn bit_io_and_checksum() {
        let mut w = BitWriter::new();
        for v in 1..300u64 {
            w.gamma(v);
            w.put(v & 0x1f, 5);
        }
        let mut r = BitReader {
            data: &w.bytes,
            pos: 0,
        };
        for v in 1..300u64 {
            assert_eq!(r.gamma("v").unwrap(), v);
            assert_eq!(r.get(5, "v").unwrap(), v & 0x1f);
        }
        assert!(r.left() < 8);
        // The standard CRC-32 check value.
        assert_eq!(crc32(b"123456789"), 0xCBF4_3926);
    }

    #[test]
    fn zigzag_round_trips() {
        for v in -300i64..300 {
            assert_eq!(unzigzag(zigzag(v)), v);
        }
        assert_eq!([0, -1, 1, -2].map(zigzag), [0, 1, 2, 3]);
    }

    /// A sketch of `curves` without shading, colour or region.
    fn bare_sketch(
        width: u32,
        height: u32,
        seed: u64,
        curves: Vec<crate::sketch::Curve>,
    ) -> crate::sketch::Sketch {
        crate::sketch::Sketch {
            width,
            height,
            seed,
            curves,
            rho_off: crate::sketch::RhoPrior {
                weight: [0.5, 0.5],
                mean: [1.0, 4.0],
                sigma: [0.5, 2.0],
            },
            shading: Default::default(),
            colour: crate::sketch::ColourMap {
                uv: vec![[0.0, 0.0]; COLOUR_BINS],
            },
            region: Vec::new(),
            along_across: None,
        }
    }

    /// A version-1 file (no region) is the version-2 payload without the region's one bit
    /// (an empty region is γ(1) = "1"); it reads as the whole image.
    #[test]
    fn version_1_files_still_read() {
        let s = bare_sketch(40, 30, 5, Vec::new());
        let (mut payload, bits) = pack(&codes(&s), 2, true);
        assert_eq!(bits[4], 1);
        let at: usize = bits[..4].iter().sum();
        payload[at / 8] &= !(0x80u8 >> (at % 8));
        if at.is_multiple_of(8) {
            payload.pop();
        }
        let total = 4 + 1 + payload.len() + 4;
        let mut v1 = MAGIC.to_vec();
        v1.push(1);
        v1.extend(leb128(total as u64));
        v1.extend(&payload);
        let crc = crc32(&v1);
        v1.extend(crc.to_le_bytes());
        let back = from_czs(&v1, Path::new("old.czs")).unwrap();
        assert_eq!(back, quantise(&s));
        let mut v6 = to_czs(&s);
        v6[3] = CZS_VERSION + 1;
        let m = from_czs(&v6, Path::new("new.czs")).unwrap_err().to_string();
        assert!(m.contains(&format!("version {}", CZS_VERSION + 1)), "{m}");
    }

    /// A sketch with every kind, turns, refined and plain sides, undecided labels: versions 3
    /// to 5 read back what version 2 does, version 3 in fewer bytes, and damage past the
    /// curves' start is caught.
    #[test]
    fn version_3_reads_back_what_version_2_does() {
        use crate::sketch::{Curve, Kind, Primitive};
        let mut state = 7u64;
        let mut rnd = || {
            state = state
                .wrapping_mul(6364136223846793005)
                .wrapping_add(1442695040888963407);
            (state >> 33) as f32 / (1u64 << 31) as f32
        };
        let kinds = [
            Kind::Boundary,
            Kind::Source,
            Kind::Occluding,
            Kind::Dividing,
            Kind::Stream,
        ];
        let mut curves = Vec::new();
        for k in 0..40 {
            let n = 1 + (rnd() * 20.0) as usize;
            let mut axis = rnd() * 3.0;
            let x0 = 130.0 + rnd() * 120.0;
            let prims = (0..n)
                .map(|j| {
                    axis += (rnd() - 0.5) * 0.6;
                    let a = (rnd() - 0.5) * 0.9;
                    Primitive {
                        shift: 0.0,
                        x: x0 + 3.0 * j as f32,
                        y: 100.0 + rnd() * 100.0,
                        axis,
                        rho: rnd() * 30.0,
                        side: [a, if k % 3 == 0 { -a } else { (rnd() - 0.5) * 0.9 }],
                    }
                })
                .collect();
            let r = rnd();
            curves.push(Curve {
                kind: kinds[k % 5],
                prims,
                dirs: [
                    if r < 0.1 {
                        0
                    } else if r < 0.55 {
                        1
                    } else {
                        -1
                    },
                    1,
                ],
            });
        }
        let s = bare_sketch(400, 300, 9, curves);
        let c = codes(&s);
        let (v2, _) = assemble(&c, 2, true);
        let (v3, bits) = assemble(&c, 3, true);
        let (v4, _) = assemble(&c, 4, true);
        let a = from_czs(&v2, Path::new("v2.czs")).unwrap();
        let b = from_czs(&v3, Path::new("v3.czs")).unwrap();
        assert_eq!(a, quantise(&s));
        assert_eq!(b, a);
        assert_eq!(from_czs(&v4, Path::new("v4.czs")).unwrap(), a);
        assert!(v3.len() < v2.len(), "{} vs {} bytes", v3.len(), v2.len());
        let frame = 4 + leb128(v3.len() as u64).len() + 4;
        assert_eq!(
            bits.iter().sum::<usize>(),
            8 * (v3.len() - frame),
            "{bits:?}"
        );
        // Every single-byte change is refused (the checksum), never a panic.
        for k in 0..v3.len() {
            let mut bad = v3.clone();
            bad[k] ^= 0x10;
            assert!(from_czs(&bad, Path::new("bad.czs")).is_err(), "byte {k}");
        }

        // Version 5, with a region (two polygons, one a hole): curves in any order read back
        // as versions 2 and 4 read them (a permutation); in the order `paint_order` gives,
        // with the same painting, in fewer bytes than version 4 and than any order.
        let mut s = s;
        s.region = vec![
            vec![
                [20, 10],
                [380, 14],
                [395, 290],
                [160, 299],
                [0, 300],
                [3, 150],
            ],
            vec![[100, 100], [100, 140], [190, 141], [191, 99]],
        ];
        // A colour map with the codes' extremes and uneven steps.
        s.colour.uv = (0..COLOUR_BINS)
            .map(|k| [-32.0 + 8.5 * k as f32, 94.0 - (k * k) as f32 / 2.0])
            .collect();
        let c = codes(&s);
        let (v4, _) = assemble(&c, 4, true);
        let (v5, bits) = assemble(&c, 5, true);
        let a = from_czs(&v4, Path::new("v4.czs")).unwrap();
        assert_eq!(a, quantise(&s));
        assert_eq!(from_czs(&v5, Path::new("v5.czs")).unwrap(), a);
        let frame = 4 + leb128(v5.len() as u64).len() + 4;
        assert_eq!(
            bits.iter().sum::<usize>(),
            8 * (v5.len() - frame),
            "{bits:?}"
        );
        let unordered = v5.len();
        let q = quantise(&s);
        s.curves = paint_order(q.curves.clone(), 400, 300);
        assert_ne!(s.curves, q.curves);
        let (a, b) = (
            crate::sketch::prim::paint(&q.curves, 400, 300, None),
            crate::sketch::prim::paint(&s.curves, 400, 300, None),
        );
        assert!(a
            .theta
            .iter()
            .zip(&b.theta)
            .all(|(x, y)| x.to_bits() == y.to_bits()));
        let c = codes(&s);
        let ((v4, b4), (v5, b5)) = (assemble(&c, 4, true), assemble(&c, 5, true));
        let a = from_czs(&v4, Path::new("v4.czs")).unwrap();
        assert_eq!(a, quantise(&s));
        assert_eq!(from_czs(&v5, Path::new("v5.czs")).unwrap(), a);
        assert!(v5.len() < v4.len(), "{} vs {} bytes", v5.len(), v4.len());
        assert!(v5.len() < unordered, "{} vs {unordered} bytes", v5.len());
        assert!(b5[1] < b4[1] && b5[4] < b4[4], "{b5:?} vs {b4:?}");
        for k in 0..v5.len() {
            let mut bad = v5.clone();
            bad[k] ^= 0x10;
            assert!(from_czs(&bad, Path::new("bad.czs")).is_err(), "byte {k}");
        }
        // Damage under a valid checksum (what a fuzzer cannot reach through the CRC): read
        // as some sketch or refused, never a panic or a hang.
        let body = v5.len() - 4;
        for k in frame - 4..body {
            for flip in [0x01u8, 0x80, 0xff] {
                let mut bad = v5.clone();
                bad[k] ^= flip;
                let crc = crc32(&bad[..body]);
                bad[body..].copy_from_slice(&crc.to_le_bytes());
                let _ = from_czs(&bad, Path::new("bad.czs"));
            }
        }

        // Version 6 adds the along/across ratio in one byte; version 5 of the same sketch
        // reads back without it, everything else equal.
        s.along_across = Some(0.105);
        let c = codes(&s);
        let ((v5, _), (v6, b6)) = (assemble(&c, 5, true), assemble(&c, 6, true));
        let q = quantise(&s);
        let six = from_czs(&v6, Path::new("v6.czs")).unwrap();
        assert_eq!(six, q);
        let t = six.along_across.unwrap();
        assert!((t / 0.105 - 1.0).abs() < 0.023, "{t}");
        let five = from_czs(&v5, Path::new("v5.czs")).unwrap();
        assert_eq!(five.along_across, None);
        assert_eq!(
            crate::sketch::Sketch {
                along_across: t.into(),
                ..five
            },
            q
        );
        assert_eq!(v6.len(), v5.len() + 1);
        assert_eq!(b6[0], b5[0] + 8);

        // The ledger of the range-coded part: its fields add up to that part less the
        // coder's flush, and each field is charged with its own symbols (dropping the
        // last curve takes bytes from the curves' fields, none from the colour map's).
        let ledger = |s: &crate::sketch::Sketch| {
            let z = czs_sizes(s);
            let sum: f64 = z.fields.values().sum();
            let coded = (z.colour + z.region + z.curves) as f64;
            assert!(
                sum <= coded && sum >= coded - 6.0,
                "{sum} B in the ledger, {coded} B coded: {:?}",
                z.fields
            );
            z.fields
        };
        let all = ledger(&s);
        for f in [
            "colour", "region", "start", "axis", "turn", "side", "contrast",
        ] {
            assert!(all[f] > 0.0, "{f}: {all:?}");
        }
        let mut fewer = s.clone();
        fewer.curves.pop();
        let less = ledger(&fewer);
        assert_eq!(less["colour"], all["colour"]);
        assert_eq!(less["region"], all["region"]);
        for f in ["start", "axis", "turn", "side", "contrast"] {
            assert!(less[f] < all[f], "{f}: {less:?} vs {all:?}");
        }
    }
}
