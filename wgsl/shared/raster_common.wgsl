// The uniform of both render passes, `render/strand_raster.wgsl` and `render/mesh_raster.wgsl`
// (one buffer serves both draws). Rust side: `stages::raster_common::Config`.
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
