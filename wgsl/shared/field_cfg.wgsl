// The uniform of every `field_*.wgsl` stage; Rust side: `stages::field_cfg::Config`.
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
