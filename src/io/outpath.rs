//! Checks of a command's single output file before any work: its extension names a format
//! the command writes, its folder exists, and it is none of the files the command reads.
//! Without them `render --out model/strands.hair` replaced the model's strands with a PNG,
//! and `--out x.jpg` wrote PNG bytes under a JPEG name.

use crate::error::{Error, Result};
use std::path::{Path, PathBuf};

/// A format an output file is written in, chosen by its extension.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Format {
    Png,
    Jpeg,
    Svg,
}

impl Format {
    /// The extensions (lower case) that name the format.
    pub fn extensions(self) -> &'static [&'static str] {
        match self {
            Format::Png => &["png"],
            Format::Jpeg => &["jpg", "jpeg"],
            Format::Svg => &["svg"],
        }
    }

    /// The `image` crate's encoder for a raster format.
    pub fn image_format(self) -> Option<image::ImageFormat> {
        match self {
            Format::Png => Some(image::ImageFormat::Png),
            Format::Jpeg => Some(image::ImageFormat::Jpeg),
            Format::Svg => None,
        }
    }

    /// The format `path`'s extension names, if any (case-insensitive).
    pub fn of(path: &Path) -> Option<Format> {
        let ext = path.extension()?.to_str()?.to_ascii_lowercase();
        [Format::Png, Format::Jpeg, Format::Svg]
            .into_iter()
            .find(|f| f.extensions().contains(&ext.as_str()))
    }
}

/// Checks `out` before any work and returns the format its extension names: not one of
/// `inputs` (a file is an input itself; a folder makes every path inside it one), a type in
/// `formats`, its folder existing. An input or a wrong type is a usage error (64), a missing
/// folder a file system one (74).
pub fn check(out: &Path, formats: &[Format], inputs: &[&Path]) -> Result<Format> {
    // First, as the worst mistake: `render --out model/strands.hair` is wrong twice.
    refuse_inputs(out, inputs)?;
    let Some(format) = Format::of(out).filter(|f| formats.contains(f)) else {
        let mut expected: Vec<String> = formats
            .iter()
            .map(|f| format!(".{}", f.extensions()[0]))
            .collect();
        let last = expected.pop().unwrap_or_default();
        let expected = match expected.is_empty() {
            true => last,
            false => format!("{} or {last}", expected.join(", ")),
        };
        let got = match out.extension() {
            Some(e) => format!("\".{}\"", e.to_string_lossy()),
            None => "no extension".into(),
        };
        return Err(Error::Invalid(format!(
            "{}: the output type is chosen by extension and {got} is not one this command \
             writes: expected {}",
            out.display(),
            expected
        )));
    };
    require_folder(out)?;
    Ok(format)
}

/// Checks a command's single output file whose type its writer checks by extension (strand
/// and sketch files): not one of `inputs`, not an existing folder (64), its folder existing
/// (74). Without it `convert a.hair a.hair` rewrote its input and `export --to somedir`
/// failed only after reading the model.
pub fn check_file(out: &Path, inputs: &[&Path]) -> Result<()> {
    refuse_inputs(out, inputs)?;
    if out.is_dir() {
        return Err(Error::Invalid(format!(
            "{}: is a folder; this command writes one file there: give a file name",
            out.display()
        )));
    }
    require_folder(out)
}

/// Refuses `out` when the folder it would be written in does not exist (74).
pub fn require_folder(out: &Path) -> Result<()> {
    let parent = match out.parent() {
        Some(p) if !p.as_os_str().is_empty() => p,
        _ => Path::new("."),
    };
    if parent.is_dir() {
        return Ok(());
    }
    Err(Error::io(
        parent,
        std::io::Error::new(
            std::io::ErrorKind::NotFound,
            format!(
                "the output folder of {} does not exist",
                out.file_name().unwrap_or_default().to_string_lossy()
            ),
        ),
    ))
}

/// Refuses `out` when it is one of `inputs` or lies inside an input folder, comparing
/// resolved paths (so `./m/../m/strands.hair` is `m/strands.hair`, symbolic links followed).
pub fn refuse_inputs(out: &Path, inputs: &[&Path]) -> Result<()> {
    let Some(target) = resolve(out) else {
        return Ok(());
    };
    for input in inputs {
        let Ok(inp) = input.canonicalize() else {
            continue; // an input that does not exist is reported by its reader
        };
        let clash = if inp.is_dir() {
            target.starts_with(&inp)
        } else {
            target == inp
        };
        if clash {
            return Err(Error::Invalid(format!(
                "{}: the output would overwrite {} {}, which this command reads; write it \
                 elsewhere",
                out.display(),
                if inp.is_dir() {
                    "a file in the input folder"
                } else {
                    "the input"
                },
                input.display()
            )));
        }
    }
    Ok(())
}

/// `path` resolved: itself when it exists, else its resolved folder joined with its name.
fn resolve(path: &Path) -> Option<PathBuf> {
    if let Ok(p) = path.canonicalize() {
        return Some(p);
    }
    let name = path.file_name()?;
    let parent = match path.parent() {
        Some(p) if !p.as_os_str().is_empty() => p,
        _ => Path::new("."),
    };
    Some(parent.canonicalize().ok()?.join(name))
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn formats_by_extension() {
        assert_eq!(Format::of(Path::new("a/b.PNG")), Some(Format::Png));
        assert_eq!(Format::of(Path::new("b.jpeg")), Some(Format::Jpeg));
        assert_eq!(Format::of(Path::new("b.Jpg")), Some(Format::Jpeg));
        assert_eq!(Format::of(Path::new("b.svg")), Some(Format::Svg));
        assert_eq!(Format::of(Path::new("b.tiff")), None);
        assert_eq!(Format::of(Path::new("b")), None);
    }

    #[test]
    fn inputs_and_their_folders_are_refused() {
        let d = tempfile::tempdir().unwrap();
        let model = d.path().join("model");
        std::fs::create_dir(&model).unwrap();
        std::fs::write(model.join("strands.hair"), b"x").unwrap();
        std::fs::write(d.path().join("a.png"), b"x").unwrap();
        let a = d.path().join("a.png");
        let png = [Format::Png];
        // The same file by another spelling.
        let other = model.join("..").join("a.png");
        let e = check(&other, &png, &[&a]).unwrap_err().to_string();
        assert!(e.contains("overwrite the input"), "{e}");
        // A folder input covers what is inside it, existing or not.
        let e = refuse_inputs(&model.join("strands.hair"), &[&model]).unwrap_err();
        assert!(e.to_string().contains("input folder"), "{e}");
        assert!(refuse_inputs(&model.join("new.png"), &[&model]).is_err());
        // Beside the inputs is fine, and so is an input that does not exist.
        assert_eq!(
            check(&d.path().join("b.png"), &png, &[&a, &model]).unwrap(),
            Format::Png
        );
        assert!(check(&a, &png, &[&d.path().join("gone.png")]).is_ok());
        // Wrong type, missing folder.
        let e = check(&d.path().join("b.jpg"), &png, &[]).unwrap_err();
        assert_eq!(e.exit_code(), 64);
        assert!(e.to_string().contains("expected .png"), "{e}");
        let e = check(&d.path().join("no/b.png"), &png, &[]).unwrap_err();
        assert_eq!(e.exit_code(), 74);
        assert!(e.to_string().contains("does not exist"), "{e}");
    }

    #[test]
    fn a_single_file_output_is_not_an_input_nor_a_folder() {
        let d = tempfile::tempdir().unwrap();
        let a = d.path().join("a.hair");
        std::fs::write(&a, b"x").unwrap();
        let e = check_file(&a, &[&a]).unwrap_err();
        assert_eq!(e.exit_code(), 64);
        assert!(e.to_string().contains("overwrite the input"), "{e}");
        let e = check_file(d.path(), &[&a]).unwrap_err();
        assert_eq!(e.exit_code(), 64);
        assert!(e.to_string().contains("is a folder"), "{e}");
        assert_eq!(
            check_file(&d.path().join("no/b.hair"), &[])
                .unwrap_err()
                .exit_code(),
            74
        );
        check_file(&d.path().join("b.hair"), &[&a]).unwrap();
    }
}
