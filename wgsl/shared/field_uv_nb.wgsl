// One linked neighbour's (u, v) into weighted sums, for `field_resid.wgsl` and
// `field_smooth.wgsl`; needs the including shader's `uv` binding.
fn add_nb(j: u32, w: f32, su: ptr<function, vec3<f32>>, sv: ptr<function, vec3<f32>>, d: ptr<function, f32>) {
    if w > 0.0 {
        let b = 6u * j;
        *su = *su + w * vec3<f32>(uv[b], uv[b + 1u], uv[b + 2u]);
        *sv = *sv + w * vec3<f32>(uv[b + 3u], uv[b + 4u], uv[b + 5u]);
        *d = *d + w;
    }
}
