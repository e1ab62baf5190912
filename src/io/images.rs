//! Reading images and masks with messages that name the file and the problem.

use crate::error::{Error, Result};
use std::path::Path;

/// Largest image accepted, in pixels: beyond it one f32 plane alone passes 1 GiB.
pub const MAX_PIXELS: u64 = 1 << 28;

/// Reads `path` once (so a pipe such as `/dev/stdin` works), then checks the header and
/// decodes from memory, the format guessed from the bytes.
pub fn open(path: &Path) -> Result<image::DynamicImage> {
    let bytes = std::fs::read(path).map_err(|e| Error::io(path, e))?;
    let reader = image::ImageReader::new(std::io::Cursor::new(&bytes[..]))
        .with_guessed_format()
        .map_err(|e| Error::io(path, e))?;
    if reader.format().is_none() {
        return Err(Error::bad_file(
            path,
            "not an image this build reads (PNG expected)",
        ));
    }
    let (w, h) = reader
        .into_dimensions()
        .map_err(|e| Error::bad_file(path, format!("cannot read the image header: {e}")))?;
    if w as u64 * h as u64 > MAX_PIXELS {
        return Err(Error::TooLarge {
            what: format!("{} ({w}x{h} px)", path.display()),
            needed: w as u64 * h as u64,
            limit: MAX_PIXELS,
            limit_name: "image size limit".into(),
            unit: "pixels",
        });
    }
    let mut reader = image::ImageReader::new(std::io::Cursor::new(&bytes[..]))
        .with_guessed_format()
        .map_err(|e| Error::io(path, e))?;
    reader.no_limits();
    let img = reader
        .decode()
        .map_err(|e| Error::bad_file(path, format!("cannot decode the image: {e}")))?;
    if img.width() == 0 || img.height() == 0 {
        return Err(Error::bad_file(path, "the image has no pixels"));
    }
    Ok(img)
}

/// An 8-bit RGB image (alpha dropped, 16-bit reduced).
pub fn load_rgb(path: &Path) -> Result<image::RgbImage> {
    Ok(open(path)?.to_rgb8())
}

/// A reference hair mask (drawn by hand, > 127 on hair) to score a result against: it must
/// have the size of the image at `image_path` (when that reads) and hold some hair.
pub fn load_reference_mask(path: &Path, image_path: &Path) -> Result<image::GrayImage> {
    let size = image::image_dimensions(image_path).ok();
    open_mask(path, "reference mask", size, image_path, "score against")
}

/// A hair mask of the given size: one byte per pixel, 1 where the mask is > 127.
/// `image_path` names the image it must match in the error message.
pub fn load_mask(path: &Path, width: u32, height: u32, image_path: &Path) -> Result<Vec<u8>> {
    let m = open_mask(path, "mask", Some((width, height)), image_path, "analyse")?;
    Ok(m.pixels().map(|p| (p[0] > 127) as u8).collect())
}

/// The mask at `path` as grey levels, refused (naming it as `what`) when it is not of `size`
/// (the image at `image_path`'s) or has no pixel above 127 (no hair to `use_for`).
fn open_mask(
    path: &Path,
    what: &str,
    size: Option<(u32, u32)>,
    image_path: &Path,
    use_for: &str,
) -> Result<image::GrayImage> {
    let m = open(path)?.to_luma8();
    if let Some((w, h)) = size.filter(|&s| s != m.dimensions()) {
        return Err(Error::bad_file(
            path,
            format!(
                "{what} is {}x{} px but {} is {w}x{h} px",
                m.width(),
                m.height(),
                image_path.display()
            ),
        ));
    }
    if !m.as_raw().iter().any(|&v| v > 127) {
        return Err(Error::bad_file(
            path,
            format!("{what} is empty: no pixel is above 127, so there is no hair to {use_for}"),
        ));
    }
    Ok(m)
}
