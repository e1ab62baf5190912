//! Inputs embedded in the binary so `coif demo` runs anywhere (see assets/PROVENANCE.md).

/// 512x512 portrait of Eileen Collins (NASA, public domain), as shipped by scikit-image.
pub const ASTRONAUT_PNG: &[u8] = include_bytes!("../../assets/astronaut.png");

/// Direction strokes (and a few background strokes) for the astronaut's hair, drawn by hand
/// for `coif demo` and the segmentation check (strokes.json version 1).
pub const ASTRONAUT_STROKES: &str = include_str!("../../assets/astronaut_strokes.json");

/// A comb stroke down the right-hand side of the astronaut's hair (`coif demo`).
pub const ASTRONAUT_COMB: &str = include_str!("../../assets/astronaut_comb.json");

/// A cut stroke across the astronaut's hair below the ears (`coif demo`).
pub const ASTRONAUT_CUT: &str = include_str!("../../assets/astronaut_cut.json");
