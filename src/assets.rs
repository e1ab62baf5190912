//! Inputs embedded in the binary so `coif demo` runs anywhere (see assets/PROVENANCE.md).

/// 512x512 portrait of Eileen Collins (NASA, public domain), as shipped by scikit-image.
pub const ASTRONAUT_PNG: &[u8] = include_bytes!("../assets/astronaut.png");
