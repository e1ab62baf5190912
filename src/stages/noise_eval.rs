//! Improved Perlin noise at given points, one invocation per point: the noise of the wind
//! (`wgsl/shared/noise.wgsl`, used inside `sim_step`) as a pass of its own, so that its
//! WGSL can be compared with the mirror ([`crate::sim::noise::perlin32`]) and the f64
//! reference. Pairs with `wgsl/noise_eval.wgsl`.

use crate::gpu::engine::{Bind, CpuBinding, Engine, Recording, StageDef};
use crate::sim::noise::{perlin32, perm_table};

pub const STAGE: StageDef = StageDef {
    name: "noise_eval",
    wgsl: include_str!("../../wgsl/noise_eval.wgsl"),
    bindings: &[Bind::Uniform, Bind::Read, Bind::Read, Bind::ReadWrite],
    cpu: noise_eval_cpu,
};

pub const WORKGROUP: u32 = 64;

#[derive(Clone, Copy, Debug, Default, encase::ShaderType)]
pub struct Config {
    pub n: u32,
}

/// Bindings: cfg, perm (512 u32), points (xyz f32), values (f32 out).
pub fn noise_eval_cpu(_wg: [u32; 3], b: &[CpuBinding]) {
    let cfg: Config = b[0].uniform();
    let perm = b[1].get::<u32>();
    let pts = b[2].get::<f32>();
    let mut out = b[3].get_mut::<f32>();
    for i in 0..cfg.n as usize {
        out[i] = perlin32(&perm, pts[3 * i], pts[3 * i + 1], pts[3 * i + 2]);
    }
}

/// Noise at every point on `engine` (tiles under the workgroup-count limit).
pub fn eval(engine: &Engine, points: &[[f32; 3]]) -> crate::error::Result<Vec<f32>> {
    let perm = perm_table();
    let mut values = Vec::with_capacity(points.len());
    for chunk in points.chunks(65535 * WORKGROUP as usize) {
        let cfg = Config {
            n: chunk.len() as u32,
        };
        let mut rec = Recording::default();
        let u = rec.uniform("coif.noise.cfg", &cfg);
        let p = rec.upload("coif.noise.perm", &perm);
        let x = rec.upload("coif.noise.points", chunk);
        let o = rec.alloc(
            "coif.noise.values",
            4 * chunk.len() as u64,
            crate::base::sentinel::SENTINEL,
        );
        rec.dispatch(
            &STAGE,
            [crate::gpu::engine::groups(cfg.n, WORKGROUP), 1, 1],
            &[u, p, x, o],
            &[],
        );
        rec.download(o);
        values.extend(engine.run(rec)?.get::<f32>(o));
    }
    values.truncate(points.len());
    Ok(values)
}
