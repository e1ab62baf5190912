//! `.npy` (format version 1.0) writer and reader for little-endian f32 C-order arrays,
//! byte-for-byte as numpy writes them, so ground truth and results can be inspected in Python.

use crate::error::{Error, Result};
use std::path::Path;

const MAGIC: &[u8; 6] = b"\x93NUMPY";

/// Header text (dict, space padding and final newline) as numpy writes it.
fn header_text(shape: &[usize], preamble_len: usize) -> String {
    let shape_txt = match shape.len() {
        // numpy writes a 1-tuple with a trailing comma.
        1 => format!("({},)", shape[0]),
        _ => format!(
            "({})",
            shape
                .iter()
                .map(|d| d.to_string())
                .collect::<Vec<_>>()
                .join(", ")
        ),
    };
    let mut h = format!("{{'descr': '<f4', 'fortran_order': False, 'shape': {shape_txt}, }}");
    // Pad with spaces so that preamble + header + '\n' is a multiple of 64 bytes.
    let unpadded = preamble_len + h.len() + 1;
    let pad = (64 - unpadded % 64) % 64;
    h.extend(std::iter::repeat_n(' ', pad));
    h.push('\n');
    h
}

/// Serialises an f32 array to `.npy` bytes. Panics if `shape` does not match `data`
/// (use [`write_f32`] for a checked version).
pub fn to_bytes(shape: &[usize], data: &[f32]) -> Vec<u8> {
    let n: usize = shape.iter().product();
    assert_eq!(
        n,
        data.len(),
        "npy::to_bytes: shape {shape:?} holds {n} values, data has {}",
        data.len()
    );
    let header = header_text(shape, MAGIC.len() + 2 + 2);
    assert!(header.len() <= u16::MAX as usize, "npy header too long");
    let mut out = Vec::with_capacity(10 + header.len() + data.len() * 4);
    out.extend_from_slice(MAGIC);
    out.extend_from_slice(&[1, 0]);
    out.extend_from_slice(&(header.len() as u16).to_le_bytes());
    out.extend_from_slice(header.as_bytes());
    for v in data {
        out.extend_from_slice(&v.to_le_bytes());
    }
    out
}

/// Writes an f32 array as `.npy`, atomically.
pub fn write_f32(path: &Path, shape: &[usize], data: &[f32]) -> Result<()> {
    let n = shape
        .iter()
        .try_fold(1usize, |a, &d| a.checked_mul(d))
        .ok_or_else(|| Error::Invalid(format!("npy shape {shape:?} overflows")))?;
    if n != data.len() {
        return Err(Error::Invalid(format!(
            "cannot write {}: shape {shape:?} holds {n} values but {} were given",
            path.display(),
            data.len()
        )));
    }
    crate::io::write_atomic(path, &to_bytes(shape, data))
}

/// Reads a little-endian f32 C-order `.npy` file (format version 1.x or 2.x).
pub fn read_f32(path: &Path) -> Result<(Vec<usize>, Vec<f32>)> {
    let bytes = std::fs::read(path).map_err(|e| Error::io(path, e))?;
    from_bytes(&bytes).map_err(|msg| Error::bad_file(path, msg))
}

/// Parses `.npy` bytes (what [`read_f32`] reads); the error says what is wrong.
pub fn from_bytes(bytes: &[u8]) -> std::result::Result<(Vec<usize>, Vec<f32>), String> {
    if bytes.len() < 10 || &bytes[..6] != MAGIC {
        return Err("not a .npy file (missing \\x93NUMPY magic)".into());
    }
    let major = bytes[6];
    let (hlen, hstart): (usize, usize) = match major {
        1 => (u16::from_le_bytes([bytes[8], bytes[9]]) as usize, 10),
        2 | 3 => {
            if bytes.len() < 12 {
                return Err("truncated .npy header".into());
            }
            (
                u32::from_le_bytes([bytes[8], bytes[9], bytes[10], bytes[11]]) as usize,
                12,
            )
        }
        v => return Err(format!("unsupported .npy format version {v}.{}", bytes[7])),
    };
    let hend = hstart
        .checked_add(hlen)
        .filter(|&e| e <= bytes.len())
        .ok_or("truncated .npy header")?;
    let header = std::str::from_utf8(&bytes[hstart..hend])
        .map_err(|_| "the .npy header is not valid text")?;

    let descr = dict_value(header, "descr").ok_or("the .npy header has no 'descr'")?;
    let descr = descr.trim_matches(|c| c == '\'' || c == '"');
    if descr != "<f4" {
        return Err(format!(
            "dtype '{descr}' is not supported; expected little-endian float32 ('<f4')"
        ));
    }
    let fortran =
        dict_value(header, "fortran_order").ok_or("the .npy header has no 'fortran_order'")?;
    match fortran {
        "False" => {}
        "True" => {
            return Err("Fortran-order arrays are not supported; save with C order".into());
        }
        other => return Err(format!("bad fortran_order value '{other}'")),
    }
    let shape_txt = dict_value(header, "shape").ok_or("the .npy header has no 'shape'")?;
    let inner = shape_txt
        .strip_prefix('(')
        .and_then(|s| s.strip_suffix(')'))
        .ok_or_else(|| format!("bad shape '{shape_txt}'"))?;
    let shape = inner
        .split(',')
        .map(str::trim)
        .filter(|s| !s.is_empty())
        .map(|s| s.parse::<usize>())
        .collect::<std::result::Result<Vec<_>, _>>()
        .map_err(|_| format!("bad shape '{shape_txt}'"))?;
    let n = shape
        .iter()
        .try_fold(1usize, |a, &d| a.checked_mul(d))
        .ok_or_else(|| format!("shape {shape:?} overflows"))?;
    let payload = &bytes[hend..];
    let need = n.checked_mul(4).ok_or("shape overflows")?;
    if payload.len() < need {
        return Err(format!(
            "truncated data: shape {shape:?} needs {need} bytes, the file has {}",
            payload.len()
        ));
    }
    if payload.len() > need {
        return Err(format!(
            "{} unexpected bytes after the data of shape {shape:?}",
            payload.len() - need
        ));
    }
    let data = payload
        .chunks_exact(4)
        .map(|c| f32::from_le_bytes([c[0], c[1], c[2], c[3]]))
        .collect();
    Ok((shape, data))
}

/// The raw text of `key`'s value in a numpy header dict: a quoted string, a tuple, or a word.
fn dict_value<'a>(header: &'a str, key: &str) -> Option<&'a str> {
    let pos = header
        .find(&format!("'{key}'"))
        .or_else(|| header.find(&format!("\"{key}\"")))?;
    let rest = header[pos + key.len() + 2..].trim_start();
    let rest = rest.strip_prefix(':')?.trim_start();
    let end = match rest.chars().next()? {
        '(' => rest.find(')')? + 1,
        q @ ('\'' | '"') => rest[1..].find(q)? + 2,
        _ => rest.find([',', '}']).unwrap_or(rest.len()),
    };
    Some(rest[..end].trim())
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn exact_header_for_2x3() {
        let b = to_bytes(&[2, 3], &[0.0; 6]);
        let dict = "{'descr': '<f4', 'fortran_order': False, 'shape': (2, 3), }";
        let mut expect = Vec::new();
        expect.extend_from_slice(b"\x93NUMPY\x01\x00");
        expect.extend_from_slice(&118u16.to_le_bytes());
        expect.extend_from_slice(dict.as_bytes());
        expect.extend(std::iter::repeat_n(b' ', 118 - dict.len() - 1));
        expect.push(b'\n');
        assert_eq!(&b[..128], &expect[..]);
        assert_eq!(b.len(), 128 + 24);
    }

    #[test]
    fn one_d_shape_has_trailing_comma_and_alignment() {
        for n in [0usize, 1, 5, 123456789] {
            let h = header_text(&[n], 10);
            assert!(h.contains(&format!("'shape': ({n},), ")), "{h}");
            assert_eq!((10 + h.len()) % 64, 0);
            assert!(h.ends_with('\n'));
        }
        let h = header_text(&[4, 5, 2], 10);
        assert!(h.contains("'shape': (4, 5, 2), "));
    }

    #[test]
    fn round_trip_with_nan_and_specials() {
        let dir = tempfile::tempdir().unwrap();
        let p = dir.path().join("a.npy");
        let data = vec![1.5, f32::NAN, -0.0, f32::INFINITY, f32::MIN_POSITIVE, -3.25];
        write_f32(&p, &[3, 2], &data).unwrap();
        let (shape, back) = read_f32(&p).unwrap();
        assert_eq!(shape, vec![3, 2]);
        assert_eq!(back.len(), data.len());
        for (a, b) in data.iter().zip(&back) {
            assert_eq!(a.to_bits(), b.to_bits());
        }
        // 1-D too.
        write_f32(&p, &[4], &[1.0, 2.0, 3.0, 4.0]).unwrap();
        assert_eq!(read_f32(&p).unwrap(), (vec![4], vec![1.0, 2.0, 3.0, 4.0]));
    }

    #[test]
    fn shape_mismatch_is_an_error() {
        let dir = tempfile::tempdir().unwrap();
        let p = dir.path().join("a.npy");
        let e = write_f32(&p, &[2, 2], &[1.0; 3]).unwrap_err().to_string();
        assert!(e.contains("holds 4 values but 3"), "{e}");
        assert!(!p.exists());
    }

    /// `bytes` with the first occurrence of `from` replaced by the same-length `to`.
    fn patch(bytes: &[u8], from: &[u8], to: &[u8]) -> Vec<u8> {
        assert_eq!(from.len(), to.len());
        let i = bytes.windows(from.len()).position(|w| w == from).unwrap();
        let mut b = bytes.to_vec();
        b[i..i + to.len()].copy_from_slice(to);
        b
    }

    fn read_err(bytes: &[u8]) -> String {
        let dir = tempfile::tempdir().unwrap();
        let p = dir.path().join("bad.npy");
        std::fs::write(&p, bytes).unwrap();
        let e = read_f32(&p).unwrap_err();
        assert!(matches!(e, Error::BadFile { .. }), "{e:?}");
        e.to_string()
    }

    #[test]
    fn clear_errors_for_bad_files() {
        let good = to_bytes(&[2, 3], &[1.0; 6]);

        let mut b = good.clone();
        b[1] = b'X';
        assert!(read_err(&b).contains("magic"));
        assert!(read_err(b"hello").contains("magic"));

        let e = read_err(&patch(&good, b"<f4", b"<f8"));
        assert!(e.contains("'<f8'") && e.contains("float32"), "{e}");
        let e = read_err(&patch(&good, b"<f4", b">f4"));
        assert!(e.contains("'>f4'"), "{e}");

        assert!(read_err(&patch(&good, b"False", b"True ")).contains("Fortran"));

        let e = read_err(&good[..good.len() - 3]);
        assert!(e.contains("truncated data"), "{e}");
        assert!(read_err(&good[..50]).contains("truncated"));
    }

    /// numpy must read what we write. Fails (not skips) without numpy: the format promise is
    /// only checked here.
    #[test]
    fn numpy_reads_our_files() {
        let dir = tempfile::tempdir().unwrap();
        let p = dir.path().join("n.npy");
        let data: Vec<f32> = (0..12).map(|i| i as f32 * 0.5 - 1.0).collect();
        let mut with_nan = data.clone();
        with_nan[5] = f32::NAN;
        write_f32(&p, &[2, 3, 2], &with_nan).unwrap();
        let script = "import sys, numpy as np\n\
             a = np.load(sys.argv[1])\n\
             assert a.dtype == np.float32, a.dtype\n\
             assert a.shape == (2, 3, 2), a.shape\n\
             assert np.isnan(a[0, 2, 1])\n\
             a[0, 2, 1] = 1.5\n\
             ref = (np.arange(12, dtype=np.float32) * 0.5 - 1.0).reshape(2, 3, 2)\n\
             assert (a == ref).all()\n\
             np.save(sys.argv[2], ref[1])\n\
             print('ok')\n";
        let back = dir.path().join("from_numpy.npy");
        let out = std::process::Command::new("python3")
            .arg("-c")
            .arg(script)
            .arg(&p)
            .arg(&back)
            .output();
        let out = match out {
            Ok(o) => o,
            Err(e) => panic!("cannot run python3 ({e}); install python3 and `pip install numpy`"),
        };
        let stderr = String::from_utf8_lossy(&out.stderr);
        if stderr.contains("No module named") {
            panic!("numpy is missing: `pip install numpy` to run this test\n{stderr}");
        }
        assert!(out.status.success(), "numpy rejected our file:\n{stderr}");
        // And we read what numpy writes, byte for byte the same as our own encoding.
        let (shape, vals) = read_f32(&back).unwrap();
        assert_eq!(shape, vec![3, 2]);
        assert_eq!(vals, data[6..].to_vec());
        assert_eq!(std::fs::read(&back).unwrap(), to_bytes(&[3, 2], &data[6..]));
    }
}
