// Ken Perlin's improved noise (2002) in f32, as `src/sim/noise.rs::perlin32` computes it.
// Needs `perm`: the doubled permutation table (512 u32) bound by the including shader.

fn noise_fade(t: f32) -> f32 {
    return t * t * t * (t * (t * 6.0 - 15.0) + 10.0);
}

fn noise_lerp(t: f32, a: f32, b: f32) -> f32 {
    return a + t * (b - a);
}

fn noise_grad(hash: u32, x: f32, y: f32, z: f32) -> f32 {
    let h = hash & 15u;
    let u = select(y, x, h < 8u);
    let v = select(select(z, x, h == 12u || h == 14u), y, h < 4u);
    return select(-u, u, (h & 1u) == 0u) + select(-v, v, (h & 2u) == 0u);
}

fn perlin(px: f32, py: f32, pz: f32) -> f32 {
    let fx = floor(px);
    let fy = floor(py);
    let fz = floor(pz);
    // Two's complement & 255 wraps negative cells as the reference does.
    let xi = u32(i32(fx) & 255);
    let yi = u32(i32(fy) & 255);
    let zi = u32(i32(fz) & 255);
    let x = px - fx;
    let y = py - fy;
    let z = pz - fz;
    let u = noise_fade(x);
    let v = noise_fade(y);
    let w = noise_fade(z);
    let a = perm[xi] + yi;
    let aa = perm[a] + zi;
    let ab = perm[a + 1u] + zi;
    let b = perm[xi + 1u] + yi;
    let ba = perm[b] + zi;
    let bb = perm[b + 1u] + zi;
    let x1 = x - 1.0;
    let y1 = y - 1.0;
    let z1 = z - 1.0;
    return noise_lerp(
        w,
        noise_lerp(
            v,
            noise_lerp(u, noise_grad(perm[aa], x, y, z), noise_grad(perm[ba], x1, y, z)),
            noise_lerp(u, noise_grad(perm[ab], x, y1, z), noise_grad(perm[bb], x1, y1, z))
        ),
        noise_lerp(
            v,
            noise_lerp(u, noise_grad(perm[aa + 1u], x, y, z1), noise_grad(perm[ba + 1u], x1, y, z1)),
            noise_lerp(u, noise_grad(perm[ab + 1u], x, y1, z1), noise_grad(perm[bb + 1u], x1, y1, z1))
        )
    );
}
