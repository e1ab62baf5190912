//! The hair itself: strands and the head they grow on.

pub mod head;
pub mod scene;
pub mod strands;
