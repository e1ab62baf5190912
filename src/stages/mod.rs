//! Every GPU pass: its WGSL file, its bindings, its uniform struct and its CPU mirror. Each
//! compute stage pairs with `wgsl/<name>.wgsl` ([`ALL`]), each render stage with
//! `wgsl/render/<name>.wgsl` ([`RENDER`]); the mirror reads like the shader. Pieces several
//! shaders share live in `wgsl/shared/` (see [`crate::gpu::wgsl`]) and, on the CPU side, in
//! the modules without a stage (`field_cfg`, `pm_common`, `raster_common`, `base::colour`).

pub mod cz_contrast;
pub mod cz_fill;
pub mod cz_hipass;
pub mod cz_lic;
pub mod cz_noise;
pub mod cz_tex;
pub mod cz_theta_gs;
pub mod cz_window_sums;
pub mod density_splat;
pub mod depth_raster;
pub mod dir_diffuse;
pub mod dt_filter;
pub mod edit_comb;
pub mod edit_cut;
pub mod edit_stroke;
pub mod field_cfg;
pub mod field_coarse_rhs;
pub mod field_dense;
pub mod field_prolong;
pub mod field_resid;
pub mod field_restrict;
pub mod field_smooth;
pub mod flow_down;
pub mod flow_solve;
pub mod flow_up;
pub mod flow_warp;
pub mod gabor;
pub mod grow_rk2;
pub mod klt_pyr_down;
pub mod klt_score;
pub mod klt_track;
pub mod mesh_raster;
pub mod noise_eval;
pub mod orient_fit;
pub mod orient_moments;
pub mod orient_resolve;
pub mod pm_common;
pub mod pm_cost;
pub mod pm_init;
pub mod pm_search;
pub mod pm_vote;
pub mod raster_common;
pub mod sep_blur;
pub mod sim_step;
pub mod strand_raster;
pub mod strand_shade;
pub mod strand_warp;
pub mod warp_compose;

use crate::gpu::engine::{RenderStageDef, StageDef};

/// Every registered stage, for shader validation and layout tests.
pub const ALL: &[&StageDef] = &[
    &sep_blur::STAGE,
    &gabor::STAGE,
    &orient_resolve::STAGE,
    &orient_moments::STAGE,
    &orient_fit::STAGE,
    &dir_diffuse::STAGE,
    &depth_raster::STAGE,
    &grow_rk2::STAGE,
    &density_splat::STAGE,
    &field_smooth::STAGE,
    &field_resid::STAGE,
    &field_restrict::STAGE,
    &field_prolong::STAGE,
    &field_coarse_rhs::STAGE,
    &field_dense::STAGE,
    &strand_shade::STAGE,
    &pm_init::STAGE,
    &pm_cost::STAGE,
    &pm_search::STAGE,
    &pm_vote::STAGE,
    &sim_step::STAGE,
    &noise_eval::STAGE,
    &edit_comb::STAGE,
    &edit_cut::STAGE,
    &warp_compose::STAGE,
    &strand_warp::STAGE,
    &klt_score::STAGE,
    &klt_pyr_down::STAGE,
    &klt_track::STAGE,
    &dt_filter::STAGE,
    &flow_down::STAGE,
    &flow_warp::STAGE,
    &flow_solve::STAGE,
    &flow_up::STAGE,
    &cz_fill::STAGE,
    &cz_theta_gs::STAGE,
    &cz_window_sums::STAGE,
    &cz_noise::STAGE,
    &cz_lic::STAGE,
    &cz_contrast::STAGE,
    &cz_hipass::STAGE,
];

/// Every registered render pass; the host is `crate::render::raster`.
pub const RENDER: &[&RenderStageDef] = &[
    &strand_raster::STAGE,
    &strand_raster::VIS,
    &strand_raster::VIS64,
    &mesh_raster::STAGE,
];
