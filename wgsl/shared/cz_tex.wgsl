// What the texture passes `cz_lic` and `cz_contrast` share (CZ06 §3.2): the hair domain and
// sampling over it. The including shader binds `cfg` (with `width`, `height`), `flags`
// (1 on the domain: hair with Θ and ρ), `tang` (cos Θ, sin Θ per pixel) and `src` (the image
// being sampled). CPU side: `src/stages/cz_tex.rs`, which reads the same.
//
// Positions are in sketch coordinates: pixel (i, j) covers [i, i+1) x [j, j+1), its centre is
// (i + 0.5, j + 0.5). Bilinear taps off the domain are dropped and the rest renormalised, so
// nothing off the hair leaks in.

// Index of the domain pixel under p, or -1 when p is off the image or off the domain.
fn tex_pixel(p: vec2<f32>) -> i32 {
    let f = floor(p);
    if f.x < 0.0 || f.y < 0.0 || f.x >= f32(cfg.width) || f.y >= f32(cfg.height) {
        return -1;
    }
    let i = u32(f.y) * cfg.width + u32(f.x);
    if flags[i] == 0u {
        return -1;
    }
    return i32(i);
}

// Bilinear (Σ w·src, Σ w) over the domain taps around p.
fn tex_value(p: vec2<f32>) -> vec2<f32> {
    let u = p - vec2<f32>(0.5);
    let f0 = floor(u);
    let fr = u - f0;
    let x0 = i32(f0.x);
    let y0 = i32(f0.y);
    var acc = vec2<f32>(0.0);
    for (var dy = 0; dy < 2; dy++) {
        for (var dx = 0; dx < 2; dx++) {
            let xx = x0 + dx;
            let yy = y0 + dy;
            if xx >= 0 && yy >= 0 && xx < i32(cfg.width) && yy < i32(cfg.height) {
                let j = u32(yy) * cfg.width + u32(xx);
                if flags[j] != 0u {
                    let wx = select(1.0 - fr.x, fr.x, dx == 1);
                    let wy = select(1.0 - fr.y, fr.y, dy == 1);
                    let wt = wx * wy;
                    acc = acc + vec2<f32>(wt * src[j], wt);
                }
            }
        }
    }
    return acc;
}

// The tangent at p, bilinear over the domain taps, each tap's (cos Θ, sin Θ) first turned to
// agree with `prev` (an orientation has no sign: this keeps a streamline from reversing).
// Not normalised; zero when no tap is on the domain.
fn tex_tangent(p: vec2<f32>, prev: vec2<f32>) -> vec2<f32> {
    let u = p - vec2<f32>(0.5);
    let f0 = floor(u);
    let fr = u - f0;
    let x0 = i32(f0.x);
    let y0 = i32(f0.y);
    var t = vec2<f32>(0.0);
    for (var dy = 0; dy < 2; dy++) {
        for (var dx = 0; dx < 2; dx++) {
            let xx = x0 + dx;
            let yy = y0 + dy;
            if xx >= 0 && yy >= 0 && xx < i32(cfg.width) && yy < i32(cfg.height) {
                let j = u32(yy) * cfg.width + u32(xx);
                if flags[j] != 0u {
                    let wx = select(1.0 - fr.x, fr.x, dx == 1);
                    let wy = select(1.0 - fr.y, fr.y, dy == 1);
                    var tj = tang[j];
                    if dot(tj, prev) < 0.0 {
                        tj = -tj;
                    }
                    t = t + (wx * wy) * tj;
                }
            }
        }
    }
    return t;
}
