// CZ06 §3.2, texture synthesis, step 3: high-pass. The band loses its local mean over the
// domain, out = src − num / den, with num the blurred band (0 off the domain) and den the
// blurred domain indicator (both by `sep_blur`), so what LIC and the gain leave at low
// frequency does not pile up over the rounds. Off the domain the output is 0.
// CPU mirror: `src/stages/cz_hipass.rs`.

struct Config {
    width: u32,
    height: u32,
    _pad0: u32,
    _pad1: u32,
}

@group(0) @binding(0) var<uniform> cfg: Config;
@group(0) @binding(1) var<storage, read> flags: array<u32>;
@group(0) @binding(2) var<storage, read> src: array<f32>;
@group(0) @binding(3) var<storage, read> num: array<f32>;
@group(0) @binding(4) var<storage, read> den: array<f32>;
@group(0) @binding(5) var<storage, read_write> out: array<f32>;

@compute @workgroup_size(8, 8, 1)
fn main(@builtin(global_invocation_id) gid: vec3<u32>) {
    if gid.x >= cfg.width || gid.y >= cfg.height {
        return;
    }
    let i = gid.y * cfg.width + gid.x;
    var v = 0.0;
    // den > 0 on the domain: the pixel itself is in it.
    if flags[i] != 0u && den[i] > 0.0 {
        v = src[i] - num[i] / den[i];
    }
    out[i] = v;
}
