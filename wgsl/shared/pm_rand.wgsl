// Random draws of `pm_init.wgsl` and `pm_search.wgsl`; needs `cfg` (shared/pm_common.wgsl).
// Chris Wellons' lowbias32; rand() keys it by seed, pass, pixel and draw (pm_common.rs).
fn hash(x0: u32) -> u32 {
    var x = x0;
    x ^= x >> 16u;
    x *= 0x7feb352du;
    x ^= x >> 15u;
    x *= 0x846ca68bu;
    x ^= x >> 16u;
    return x;
}

fn rand(pixel: u32, k: u32) -> u32 {
    return hash(cfg.seed ^ hash(cfg.pass_id ^ hash(pixel ^ hash(k))));
}
