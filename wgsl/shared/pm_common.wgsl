// The uniform and per-pixel flags of the four PatchMatch stages (`pm_*.wgsl`); Rust side:
// `stages::pm_common`.
struct Config {
    width: u32,
    height: u32,
    radius: u32,
    seed: u32,
    pass_id: u32,
    step: u32,
    search_radius: u32,
    fallback: u32,
    coarse_width: u32,
    coarse_height: u32,
    vote_k: f32,
    layer: u32,
}

// Per-pixel flags (pm_common.rs): to fill, has a nearest neighbour, may be a source.
const HOLE: u32 = 1u;
const TARGET: u32 = 2u;
const SOURCE: u32 = 4u;
const NONE: u32 = 0xffffffffu;
// Matching word of a pixel whose colour is not known yet; flags >> LAYER_SHIFT = peel layer.
const UNKNOWN: u32 = 0x80000000u;
const LAYER_SHIFT: u32 = 8u;
