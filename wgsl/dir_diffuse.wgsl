// One Jacobi sweep of a constrained diffusion of a 2D vector field over a mask:
//   v_p <- (sum of the 4 masked neighbours' v + lambda c_p k_p) / (their count + lambda c_p)
// where k_p is a known vector with confidence c_p (0 where nothing is known). With
// `use_orient`, the result is projected on the local orientation line t_p = (cos θ, sin θ):
// the field then stays ± the image orientation and the sweeps only choose and spread the
// sign (the dense growth direction of C13 §2.1). Without it this is a plain linear
// vector-field diffusion: it is not CZ06's fill-in (Eq. 16-17 diffuse the angle τ
// nonlinearly with a growing weight schedule), which is the `cz_fill` pass.

struct Config {
    width: u32,
    height: u32,
    lambda: f32,
    use_orient: u32,
}

@group(0) @binding(0) var<uniform> cfg: Config;
// The orientation line's unit tangent (cos θ, sin θ) interleaved per pixel, NaN off hair;
// read only with use_orient. The host computes it once: the sweeps run hundreds of times.
@group(0) @binding(1) var<storage, read> tangent: array<f32>;
// One word per pixel, nonzero inside the domain.
@group(0) @binding(2) var<storage, read> mask: array<u32>;
// Known vectors, interleaved (x, y) per pixel, and their confidence.
@group(0) @binding(3) var<storage, read> known: array<f32>;
@group(0) @binding(4) var<storage, read> known_w: array<f32>;
@group(0) @binding(5) var<storage, read> src: array<f32>;
@group(0) @binding(6) var<storage, read_write> dst: array<f32>;

fn neighbour(x: i32, y: i32, sum: ptr<function, vec2<f32>>, n: ptr<function, f32>) {
    if x < 0 || y < 0 || x >= i32(cfg.width) || y >= i32(cfg.height) {
        return;
    }
    let j = u32(y) * cfg.width + u32(x);
    if mask[j] == 0u {
        return;
    }
    *sum = *sum + vec2<f32>(src[2u * j], src[2u * j + 1u]);
    *n = *n + 1.0;
}

@compute @workgroup_size(8, 8, 1)
fn main(@builtin(global_invocation_id) gid: vec3<u32>) {
    if gid.x >= cfg.width || gid.y >= cfg.height {
        return;
    }
    let i = gid.y * cfg.width + gid.x;
    if mask[i] == 0u {
        dst[2u * i] = 0.0;
        dst[2u * i + 1u] = 0.0;
        return;
    }
    let x = i32(gid.x);
    let y = i32(gid.y);
    var sum = vec2<f32>(0.0);
    var n = 0.0;
    neighbour(x - 1, y, &sum, &n);
    neighbour(x + 1, y, &sum, &n);
    neighbour(x, y - 1, &sum, &n);
    neighbour(x, y + 1, &sum, &n);
    let c = cfg.lambda * known_w[i];
    let num = sum + c * vec2<f32>(known[2u * i], known[2u * i + 1u]);
    let den = n + c;
    var v = vec2<f32>(0.0);
    if den > 0.0 {
        v = num / den;
    }
    if cfg.use_orient == 1u {
        let t = vec2<f32>(tangent[2u * i], tangent[2u * i + 1u]);
        if t.x == t.x {
            v = dot(v, t) * t;
        }
    }
    dst[2u * i] = v.x;
    dst[2u * i + 1u] = v.y;
}
