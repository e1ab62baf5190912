//! Small shared building blocks with no knowledge of hair: grids, random numbers, mask
//! morphology, box filters, distance functions, order statistics, the buffer sentinel, the memory budget.

pub mod budget;
pub mod colour;
pub mod filter;
pub mod grid;
pub mod mask;
pub mod polyline;
pub mod rng;
pub mod sdf;
pub mod sentinel;
pub mod stats;
pub mod turn;
