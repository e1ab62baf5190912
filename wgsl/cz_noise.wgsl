// CZ06 §3.2, texture synthesis, the start: white noise on the domain, uniform in
// [−amp, amp), from an integer hash of (seed, pixel) (Chris Wellons' lowbias32) so the CPU
// mirror gives the same bits. Off the domain the output is 0.
// CPU mirror: `src/stages/cz_noise.rs`.

struct Config {
    width: u32,
    height: u32,
    seed_lo: u32,
    seed_hi: u32,
    amp: f32,
    _pad0: u32,
    _pad1: u32,
    _pad2: u32,
}

@group(0) @binding(0) var<uniform> cfg: Config;
@group(0) @binding(1) var<storage, read> flags: array<u32>;
@group(0) @binding(2) var<storage, read_write> out: array<f32>;

fn lowbias32(x0: u32) -> u32 {
    var x = x0;
    x ^= x >> 16u;
    x *= 0x7feb352du;
    x ^= x >> 15u;
    x *= 0x846ca68bu;
    x ^= x >> 16u;
    return x;
}

@compute @workgroup_size(8, 8, 1)
fn main(@builtin(global_invocation_id) gid: vec3<u32>) {
    if gid.x >= cfg.width || gid.y >= cfg.height {
        return;
    }
    let i = gid.y * cfg.width + gid.x;
    var v = 0.0;
    if flags[i] != 0u {
        let hsh = lowbias32(cfg.seed_lo ^ lowbias32(cfg.seed_hi ^ lowbias32(i)));
        // 24 bits: exact in f32, so u, 2u − 1 and the product are the same on both sides.
        let u = f32(hsh >> 8u) * (1.0 / 16777216.0);
        v = cfg.amp * (2.0 * u - 1.0);
    }
    out[i] = v;
}
