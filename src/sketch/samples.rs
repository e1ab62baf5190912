//! Real hair and fur photographs for the sketch's tests and benches, with their hair masks:
//! crops of public-domain / CC0 photos committed under `tests/data/sketch/` (provenance in
//! the README there) and the embedded astronaut. The crops are read from the source tree
//! at run time, so this is for tests run from a checkout, not for an installed binary.

use crate::analyze::segment::{segment, SegmentParams};
use crate::error::{Error, Result};
use crate::io::annot::Strokes;
use image::RgbImage;
use std::path::{Path, PathBuf};

/// The photographs.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Sample {
    /// Raccoon fur, 384×272, all fur (scipy's `face`).
    Raccoon,
    /// Chelsea the cat's forehead fur, 220×100, all fur (scikit-image's `chelsea`).
    Chelsea,
    /// The astronaut portrait, 512×512, hair segmented from its embedded strokes.
    Astronaut,
}

impl Sample {
    pub const ALL: [Sample; 3] = [Sample::Raccoon, Sample::Chelsea, Sample::Astronaut];

    pub fn name(self) -> &'static str {
        match self {
            Sample::Raccoon => "raccoon",
            Sample::Chelsea => "chelsea",
            Sample::Astronaut => "astronaut",
        }
    }
}

/// A photograph and its hair mask (row-major, W*H).
#[derive(Clone, Debug)]
pub struct SampleImage {
    pub name: &'static str,
    pub image: RgbImage,
    pub hair: Vec<bool>,
}

/// The folder of the committed crops.
pub fn data_dir() -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).join("tests/data/sketch")
}

fn read_png(path: &Path) -> Result<RgbImage> {
    let bytes = std::fs::read(path).map_err(|e| Error::io(path, e))?;
    Ok(image::load_from_memory(&bytes)
        .map_err(|e| Error::bad_file(path, format!("not a readable image: {e}")))?
        .to_rgb8())
}

/// Loads a photograph; the astronaut's hair is segmented from its strokes (a few seconds).
pub fn load(s: Sample) -> Result<SampleImage> {
    let (image, hair) = match s {
        Sample::Raccoon | Sample::Chelsea => {
            let file = if s == Sample::Raccoon {
                "raccoon_fur.png"
            } else {
                "chelsea_fur.png"
            };
            let image = read_png(&data_dir().join(file))?;
            let n = image.width() as usize * image.height() as usize;
            (image, vec![true; n])
        }
        Sample::Astronaut => {
            let image = image::load_from_memory(crate::io::assets::ASTRONAUT_PNG)
                .map_err(|e| Error::Invalid(format!("embedded astronaut: {e}")))?
                .to_rgb8();
            let strokes = Strokes::parse(
                crate::io::assets::ASTRONAUT_STROKES,
                Path::new("astronaut_strokes.json"),
                Some(image.dimensions()),
            )?;
            let mask = segment(&image, &strokes, &SegmentParams::default())?;
            let hair = mask.as_raw().iter().map(|&v| v > 127).collect();
            (image, hair)
        }
    };
    Ok(SampleImage {
        name: s.name(),
        image,
        hair,
    })
}
