// Pyramidal Lucas–Kanade (Bouguet's formulation), one invocation per feature: find where the
// template patch around `tmpl_pts[i]` (in the template pyramid) lies in the target pyramid,
// starting from `guess[i]`, coarse to fine, with Newton iterations per level.
//
// Window pixels are weighted by a Gaussian of sigma win/2 (as in klt_score, so a feature
// detected there passes the checks here): the rim, which a turning patch moves most, counts
// least.
//
// Points are vec4 (x, y, status, residual): status 1 tracked, 0 lost; residual is the mean
// absolute difference between the template patch and the target patch at the result (level 0).
// A feature is lost when its input is lost, its template patch is too flat or too
// one-dimensional to fix both coordinates (min eigenvalue of the window-averaged structure
// tensor below `min_eig`, or below `min_iso` times the max eigenvalue), or the result's
// window leaves the image.

struct Config {
    n_points: u32,
    levels: u32,
    // Level-0 size; level l+1 is ceil(w_l / 2) x ceil(h_l / 2) (klt_pyr_down's layout).
    width: u32,
    height: u32,
    // Window half size: the patch is (2 win + 1)².
    win: u32,
    iters: u32,
    // Stop a level's iterations once an update is shorter than this (level pixels).
    eps: f32,
    min_eig: f32,
    // Lost when λmin < min_iso λmax at level 0: the patch is an edge or stripes, and its
    // position along them is not determined.
    min_iso: f32,
    _pad0: u32,
    _pad1: u32,
    _pad2: u32,
}

@group(0) @binding(0) var<uniform> cfg: Config;
@group(0) @binding(1) var<storage, read> tmpl_pyr: array<f32>;
@group(0) @binding(2) var<storage, read> tmpl_pts: array<vec4<f32>>;
@group(0) @binding(3) var<storage, read> tgt_pyr: array<f32>;
@group(0) @binding(4) var<storage, read> guess: array<vec4<f32>>;
@group(0) @binding(5) var<storage, read_write> out: array<vec4<f32>>;

struct Level {
    w: u32,
    h: u32,
    off: u32,
}

fn level(l: u32) -> Level {
    var lv = Level(cfg.width, cfg.height, 0u);
    for (var k = 0u; k < l; k++) {
        lv.off = lv.off + lv.w * lv.h;
        lv.w = (lv.w + 1u) / 2u;
        lv.h = (lv.h + 1u) / 2u;
    }
    return lv;
}

struct Taps {
    i00: u32,
    i10: u32,
    i01: u32,
    i11: u32,
    fx: f32,
    fy: f32,
}

// Bilinear taps at (x, y), clamp-to-edge.
fn taps(lv: Level, p: vec2<f32>) -> Taps {
    let x = clamp(p.x, 0.0, f32(lv.w - 1u));
    let y = clamp(p.y, 0.0, f32(lv.h - 1u));
    let x0 = floor(x);
    let y0 = floor(y);
    let ix0 = u32(x0);
    let iy0 = u32(y0);
    let ix1 = min(ix0 + 1u, lv.w - 1u);
    let iy1 = min(iy0 + 1u, lv.h - 1u);
    return Taps(
        lv.off + iy0 * lv.w + ix0,
        lv.off + iy0 * lv.w + ix1,
        lv.off + iy1 * lv.w + ix0,
        lv.off + iy1 * lv.w + ix1,
        x - x0,
        y - y0,
    );
}

fn tmpl_at(lv: Level, p: vec2<f32>) -> f32 {
    let t = taps(lv, p);
    let top = (1.0 - t.fx) * tmpl_pyr[t.i00] + t.fx * tmpl_pyr[t.i10];
    let bot = (1.0 - t.fx) * tmpl_pyr[t.i01] + t.fx * tmpl_pyr[t.i11];
    return (1.0 - t.fy) * top + t.fy * bot;
}

fn tgt_at(lv: Level, p: vec2<f32>) -> f32 {
    let t = taps(lv, p);
    let top = (1.0 - t.fx) * tgt_pyr[t.i00] + t.fx * tgt_pyr[t.i10];
    let bot = (1.0 - t.fx) * tgt_pyr[t.i01] + t.fx * tgt_pyr[t.i11];
    return (1.0 - t.fy) * top + t.fy * bot;
}

fn tmpl_grad(lv: Level, q: vec2<f32>) -> vec2<f32> {
    return vec2<f32>(
        0.5 * (tmpl_at(lv, q + vec2<f32>(1.0, 0.0)) - tmpl_at(lv, q - vec2<f32>(1.0, 0.0))),
        0.5 * (tmpl_at(lv, q + vec2<f32>(0.0, 1.0)) - tmpl_at(lv, q - vec2<f32>(0.0, 1.0))),
    );
}

fn window_weight(dx: i32, dy: i32) -> f32 {
    return exp(-2.0 / f32(cfg.win * cfg.win) * f32(dx * dx + dy * dy));
}

fn finite(v: f32) -> bool {
    // NaN fails both comparisons; infinities fail the bound.
    return abs(v) <= 3.0e38;
}

@compute @workgroup_size(64, 1, 1)
fn main(@builtin(global_invocation_id) gid: vec3<u32>) {
    let i = gid.x;
    if i >= cfg.n_points {
        return;
    }
    let nan = bitcast<f32>(0x7fc00000u);
    let lost = vec4<f32>(nan, nan, 0.0, 0.0);
    let tp = tmpl_pts[i];
    let gs = guess[i];
    if tp.z == 0.0 || gs.z == 0.0 || !finite(tp.x) || !finite(tp.y) || !finite(gs.x)
        || !finite(gs.y) {
        out[i] = lost;
        return;
    }
    let r = i32(cfg.win);
    var n = 0.0;
    for (var dy = -r; dy <= r; dy++) {
        for (var dx = -r; dx <= r; dx++) {
            n = n + window_weight(dx, dy);
        }
    }
    let top = cfg.levels - 1u;
    // Displacement carried from level to level, in the current level's pixels.
    var g = (gs.xy - tp.xy) / f32(1u << top);
    var result = vec2<f32>(0.0, 0.0);
    for (var li = 0u; li <= top; li++) {
        let l = top - li;
        let lv = level(l);
        let c = tp.xy / f32(1u << l);
        var gxx = 0.0;
        var gxy = 0.0;
        var gyy = 0.0;
        for (var dy = -r; dy <= r; dy++) {
            for (var dx = -r; dx <= r; dx++) {
                let d = tmpl_grad(lv, c + vec2<f32>(f32(dx), f32(dy)));
                let wt = window_weight(dx, dy);
                gxx = gxx + wt * d.x * d.x;
                gxy = gxy + wt * d.x * d.y;
                gyy = gyy + wt * d.y * d.y;
            }
        }
        let h = 0.5 * (gxx - gyy) / n;
        let root = sqrt(h * h + (gxy / n) * (gxy / n));
        let lam_min = 0.5 * (gxx + gyy) / n - root;
        let lam_max = 0.5 * (gxx + gyy) / n + root;
        if l == 0u && (!(lam_min >= cfg.min_eig) || !(lam_min >= cfg.min_iso * lam_max)) {
            out[i] = lost;
            return;
        }
        let det = gxx * gyy - gxy * gxy;
        var v = vec2<f32>(0.0, 0.0);
        // A degenerate coarse level keeps the carried displacement; finer levels decide.
        if lam_min > 0.0 && det > 0.0 {
            for (var k = 0u; k < cfg.iters; k++) {
                var bx = 0.0;
                var by = 0.0;
                for (var dy = -r; dy <= r; dy++) {
                    for (var dx = -r; dx <= r; dx++) {
                        let q = c + vec2<f32>(f32(dx), f32(dy));
                        let d = tmpl_grad(lv, q);
                        let diff = window_weight(dx, dy) * (tmpl_at(lv, q) - tgt_at(lv, q + g + v));
                        bx = bx + diff * d.x;
                        by = by + diff * d.y;
                    }
                }
                let step = vec2<f32>(gyy * bx - gxy * by, gxx * by - gxy * bx) / det;
                v = v + step;
                if !(length(step) >= cfg.eps) {
                    break;
                }
            }
        }
        if l > 0u {
            g = 2.0 * (g + v);
        } else {
            result = c + g + v;
        }
    }
    let w = f32(r);
    if !finite(result.x) || !finite(result.y) || result.x < w || result.y < w
        || result.x > f32(cfg.width - 1u) - w || result.y > f32(cfg.height - 1u) - w {
        out[i] = lost;
        return;
    }
    let lv0 = level(0u);
    var res = 0.0;
    for (var dy = -r; dy <= r; dy++) {
        for (var dx = -r; dx <= r; dx++) {
            let o = vec2<f32>(f32(dx), f32(dy));
            res = res + window_weight(dx, dy) * abs(tmpl_at(lv0, tp.xy + o) - tgt_at(lv0, result + o));
        }
    }
    out[i] = vec4<f32>(result, 1.0, res / n);
}
