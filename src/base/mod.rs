//! Small shared building blocks with no knowledge of hair: grids, random numbers.

pub mod colour;
pub mod grid;
pub mod rng;
