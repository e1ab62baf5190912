// Residual of the normal equations (L² + P) v = P c of C13 Eq. (3) from the mixed residual:
// with r1 = u - L v and r2 = b - L u - p v (fine level, σ = 1, f1 = 0),
//   b - L L v - p v = r2 + L r1.
// Three floats per cell, zero outside H; the host downloads it for the convergence check.
struct Config {
    nx: u32,
    ny: u32,
    nz: u32,
    colour: u32,
    sigma: f32,
    mode: u32,
    cnx: u32,
    cny: u32,
    cnz: u32,
    count: u32,
}

@group(0) @binding(0) var<uniform> cfg: Config;
@group(0) @binding(1) var<storage, read> cellw: array<f32>;
@group(0) @binding(2) var<storage, read> r: array<f32>;
@group(0) @binding(3) var<storage, read_write> res: array<f32>;

fn add_nb(j: u32, s: ptr<function, vec3<f32>>, d: ptr<function, f32>) {
    if cellw[j] >= 0.0 {
        let b = 6u * j;
        *s = *s + vec3<f32>(r[b], r[b + 1u], r[b + 2u]);
        *d = *d + 1.0;
    }
}

@compute @workgroup_size(4, 4, 4)
fn main(@builtin(global_invocation_id) gid: vec3<u32>) {
    let x = gid.x;
    let y = gid.y;
    let z = gid.z;
    if x >= cfg.nx || y >= cfg.ny || z >= cfg.nz {
        return;
    }
    let i = x + cfg.nx * (y + cfg.ny * z);
    var out = vec3<f32>(0.0);
    if cellw[i] >= 0.0 {
        let sy = cfg.nx;
        let sz = cfg.nx * cfg.ny;
        var s = vec3<f32>(0.0);
        var d = 0.0;
        if x > 0u { add_nb(i - 1u, &s, &d); }
        if x + 1u < cfg.nx { add_nb(i + 1u, &s, &d); }
        if y > 0u { add_nb(i - sy, &s, &d); }
        if y + 1u < cfg.ny { add_nb(i + sy, &s, &d); }
        if z > 0u { add_nb(i - sz, &s, &d); }
        if z + 1u < cfg.nz { add_nb(i + sz, &s, &d); }
        let b = 6u * i;
        let r1 = vec3<f32>(r[b], r[b + 1u], r[b + 2u]);
        let r2 = vec3<f32>(r[b + 3u], r[b + 4u], r[b + 5u]);
        out = r2 + cfg.sigma * (s - d * r1);
    }
    res[3u * i] = out.x;
    res[3u * i + 1u] = out.y;
    res[3u * i + 2u] = out.z;
}
