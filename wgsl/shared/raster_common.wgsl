// The uniform of the render passes, `render/strand_raster.wgsl`, `render/mesh_raster.wgsl` and
// `render/strand_vis.wgsl` (one buffer serves them all), and the strand segment the two strand
// passes read. Rust side: `stages::raster_common::Config`, `stages::strand_raster::SegRec`.
struct Config {
    width: u32,
    height: u32,
    samples: u32,
    half_width: f32,
    // 2 / width and 2 / height: screen px -> NDC.
    ndc_scale_x: f32,
    ndc_scale_y: f32,
    // Strand photo colour (unused by the mesh pass). 0: vertex colours; 1: photo colour;
    // 2: photo colour, HSV-adjusted.
    photo: u32,
    photo_half_width: f32,
    hue_deg: f32,
    saturation: f32,
    value: f32,
    _pad: u32,
}

// Host-prepared segment (`SegRec`): screen px, depth already mapped to [0, 1] (0 = near).
struct Seg {
    p0: vec2<f32>,
    p1: vec2<f32>,
    z0: f32,
    z1: f32,
    strand: u32,
    // For the compute walks: the segment's index within its chunk (the host reorders a
    // chunk); unused by the render pipeline.
    local: u32,
    c0: vec4<f32>,
    c1: vec4<f32>,
    // Photo points of the ends: o0 = o.xy, o1 = o.zw.
    o: vec4<f32>,
}
