// One half-sweep of red-black nonlinear Gauss-Seidel for the orientation field of CZ06
// Step 1 (§4.1, Eq. 25 with its signs corrected so that the flow lowers the energy).
//
// The field is stored as the double-angle unit vector z = (cos 2θ, sin 2θ), so no update
// needs a trigonometric function. The energy over the free pixels is
//   Σ_free A (1 − cos(2θ − 2θo)) + Σ_edges (1/2λθ²) (1 − cos(2θu − 2θv)),
// A = s²/4σθ², θo the gradient angle + π/2; its exact minimiser in one free pixel given
// its neighbours is
//   z_v = normalise(A e^{2iθo} + (1/2λθ²) Σ_u z_u),
// and `data` holds A e^{2iθo} = −(gx² − gy², 2 gx gy) / 4σθ². Pixels of one colour
// ((x + y) mod 2 = parity) do not neighbour each other, so updating all of them at once is
// an exact coordinate descent: the energy never rises.
//
// flags: 0 off the hair (neither updated nor a neighbour), 1 free, 2 fixed by the sketch.
// Each dispatch reads `src` and writes every pixel of `dst` (copies where not updated), so
// a sweep is two dispatches src → dst → src with parity 0 then 1.

struct Config {
    width: u32,
    height: u32,
    parity: u32,
    // 1/2λθ², the weight of a neighbour (½ with the paper's λθ = 1).
    half_smooth: f32,
}

@group(0) @binding(0) var<uniform> cfg: Config;
@group(0) @binding(1) var<storage, read> data: array<vec2<f32>>;
@group(0) @binding(2) var<storage, read> flags: array<u32>;
@group(0) @binding(3) var<storage, read> src: array<vec2<f32>>;
@group(0) @binding(4) var<storage, read_write> dst: array<vec2<f32>>;

fn neighbour(x: i32, y: i32) -> vec2<f32> {
    if x < 0 || y < 0 || x >= i32(cfg.width) || y >= i32(cfg.height) {
        return vec2<f32>(0.0);
    }
    let j = u32(y) * cfg.width + u32(x);
    if flags[j] == 0u {
        return vec2<f32>(0.0);
    }
    return src[j];
}

@compute @workgroup_size(8, 8, 1)
fn main(@builtin(global_invocation_id) gid: vec3<u32>) {
    if gid.x >= cfg.width || gid.y >= cfg.height {
        return;
    }
    let i = gid.y * cfg.width + gid.x;
    let z = src[i];
    if flags[i] != 1u || ((gid.x + gid.y) & 1u) != cfg.parity {
        dst[i] = z;
        return;
    }
    let x = i32(gid.x);
    let y = i32(gid.y);
    let nb = neighbour(x - 1, y) + neighbour(x + 1, y) + neighbour(x, y - 1) + neighbour(x, y + 1);
    let sum = data[i] + cfg.half_smooth * nb;
    let n2 = dot(sum, sum);
    // No data and neighbours that cancel: the energy is flat in θ here, keep it.
    if n2 > 1e-24 {
        dst[i] = sum / sqrt(n2);
    } else {
        dst[i] = z;
    }
}
