//! Hair through a video (C13 §3–4): a strand model built on a reference frame r is carried
//! through the clip, S_i = T_i(S_r), by the head's rigid motion M_i and a 2D warp W*_i that
//! blends tracked features (W†_i) with orientation-field flow (V_i) by Eq. (6); Eq. (7)
//! moves each vertex.
//!
//! `frames` loads a clip, `flow` computes V_i on orientation fields, `features` tracks
//! sparse points and `diffuse` spreads them into W†_i, `warp` holds Eq. (6) and (7),
//! `head` the head's motion, `track` the per-frame recursion and `run` the command.

pub mod diffuse;
pub mod features;
pub mod flow;
pub mod frames;
pub mod head;
pub mod run;
pub mod track;
pub mod transfer;
pub mod warp;
