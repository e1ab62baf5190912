// CZ06 §3.1, the fill-in of the vector field from the sketch: one red-black half-sweep of
// the nonlinear Gauss-Seidel flow of Eq. (16),
//   ∂τ_v/∂t = Σ_{u ∈ ∂v} w(u) sin(τ_u − τ_v),
// taken to its fixed point at each pixel, τ_v = arg Σ_u w(u) e^{iτ_u}, together with the
// growing weight schedule of Eq. (17),
//   w_v ← w_v + 0.2 (mean_{u ∈ ∂v} w(u) − w_v),
// which starts at 1 on the sketch and 0 off it, so the sketch speaks first and filled pixels
// gain a say as they settle. The mean runs over the 4-neighbours inside the domain (¼Σ in the
// interior); at the mask edge it is over the ones that exist, so w still tends to 1 there.
//
// Angles are held as unit vectors e^{iτ}: the update is then a weighted sum and a
// normalisation, with no atan2 or cos/sin per pixel (the host converts to and from angles
// once per batch of sweeps). They are directions τ (period 2π) or doubled orientations 2θ,
// the same flow for an undirected field: the pass need not know which. A pixel's vector
// means something only where its weight is > 0 (a clamped pixel, or one that has been
// reached); pixels none of whose neighbours has weight yet stay unset.
//
// Pixel classes: 0 outside the domain (not hair, or hair the sketch cannot reach), 1 free,
// 2 clamped (the sketch: angle and weight 1 fixed), 3 axis-constrained: its angle is its
// orientation `cons` (a unit vector) or its opposite, whichever the neighbours favour (a
// sketch pixel whose orientation is known but not its direction, in the directed fill).
//
// Threads cover half the x range: x = 2 gid.x + ((y + colour) & 1); every 4-neighbour has the
// other colour, so the update is in place and race-free. `delta` receives each updated
// pixel's change as the chord |e_new − e_old| (2 for a pixel set for the first time, 0 for
// one still unset): the host turns it into an angle, 2 asin(chord / 2), every few sweeps to
// decide convergence.

struct Config {
    width: u32,
    height: u32,
    colour: u32,
}

@group(0) @binding(0) var<uniform> cfg: Config;
@group(0) @binding(1) var<storage, read> kind: array<u32>;
// Unit vector of the orientation of class-3 pixels; unread elsewhere.
@group(0) @binding(2) var<storage, read> cons: array<vec2<f32>>;
// Unit vector e^{iτ} (or e^{2iθ}) per pixel.
@group(0) @binding(3) var<storage, read_write> dir: array<vec2<f32>>;
@group(0) @binding(4) var<storage, read_write> wt: array<f32>;
@group(0) @binding(5) var<storage, read_write> delta: array<f32>;

fn gather(j: u32, s: ptr<function, vec2<f32>>, sw: ptr<function, f32>, n: ptr<function, f32>) {
    if kind[j] == 0u {
        return;
    }
    *n = *n + 1.0;
    let wu = wt[j];
    if wu > 0.0 {
        *sw = *sw + wu;
        *s = *s + wu * dir[j];
    }
}

@compute @workgroup_size(8, 8, 1)
fn main(@builtin(global_invocation_id) gid: vec3<u32>) {
    let y = gid.y;
    let x = 2u * gid.x + ((y + cfg.colour) & 1u);
    if x >= cfg.width || y >= cfg.height {
        return;
    }
    let i = y * cfg.width + x;
    let c = kind[i];
    if c == 0u || c == 2u {
        return;
    }
    var s = vec2<f32>(0.0);
    var sw = 0.0;
    var n = 0.0;
    if x > 0u {
        gather(i - 1u, &s, &sw, &n);
    }
    if x + 1u < cfg.width {
        gather(i + 1u, &s, &sw, &n);
    }
    if y > 0u {
        gather(i - cfg.width, &s, &sw, &n);
    }
    if y + 1u < cfg.height {
        gather(i + cfg.width, &s, &sw, &n);
    }
    if n == 0.0 {
        return;
    }
    let w_old = wt[i];
    var d = 0.0;
    if sw > 0.0 {
        // s / |s|, scaled first: far from the sketch the weights are tiny and |s|² would
        // underflow. An exactly cancelled sum points at angle 0, as atan2(0, 0) does.
        var e = vec2<f32>(1.0, 0.0);
        let m = max(abs(s.x), abs(s.y));
        if m > 0.0 {
            let t = s / m;
            e = t / sqrt(dot(t, t));
        }
        if c == 3u {
            e = cons[i];
            if dot(s, e) < 0.0 {
                e = -e;
            }
        }
        if w_old > 0.0 {
            d = length(e - dir[i]);
        } else {
            d = 2.0;
        }
        dir[i] = e;
    }
    delta[i] = d;
    wt[i] = w_old + 0.2 * (sw / n - w_old);
}
