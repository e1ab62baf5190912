// Hair density for refinement (C13 §2.2, ρ in Eq. 5): every strand vertex adds 1 to the grid
// cell holding it (floor of its grid coordinates) with an integer atomic, so the result does
// not depend on the order the invocations run in. Vertices outside the grid (or NaN) add
// nothing. A 2D dispatch covers more than 65535 workgroups; `row` = invocations per row.

struct Config {
    nx: u32,
    ny: u32,
    nz: u32,
    n_verts: u32,
    row: u32,
}

@group(0) @binding(0) var<uniform> cfg: Config;
// Vertices, interleaved (x, y, z), in grid coordinates.
@group(0) @binding(1) var<storage, read> verts: array<f32>;
@group(0) @binding(2) var<storage, read_write> density: array<atomic<u32>>;

@compute @workgroup_size(256, 1, 1)
fn main(@builtin(global_invocation_id) gid: vec3<u32>) {
    let i = gid.x + gid.y * cfg.row;
    if i >= cfg.n_verts {
        return;
    }
    let q = vec3<f32>(verts[3u * i], verts[3u * i + 1u], verts[3u * i + 2u]);
    let n = vec3<f32>(f32(cfg.nx), f32(cfg.ny), f32(cfg.nz));
    if !(q.x >= 0.0 && q.y >= 0.0 && q.z >= 0.0 && q.x < n.x && q.y < n.y && q.z < n.z) {
        return;
    }
    let c = vec3<u32>(floor(q));
    atomicAdd(&density[c.x + cfg.nx * (c.y + cfg.ny * c.z)], 1u);
}
