//! Inputs embedded in the binary so `coif demo` runs anywhere (see assets/PROVENANCE.md).

/// 512x512 portrait of Eileen Collins (NASA, public domain), as shipped by scikit-image.
pub const ASTRONAUT_PNG: &[u8] = include_bytes!("../../assets/astronaut.png");

/// Direction strokes (and a few background strokes) for the astronaut's hair, drawn by hand
/// for `coif demo` and the segmentation check (strokes.json version 1).
pub const ASTRONAUT_STROKES: &str = include_str!("../../assets/astronaut_strokes.json");
