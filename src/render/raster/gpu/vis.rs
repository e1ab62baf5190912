//! The strands as compute passes (`wgsl/render/strand_vis.wgsl`, whose header gives the
//! passes and why): used for 4x MSAA frames with strands, after the render pipelines have
//! drawn the background and the mesh into a stored MSAA target.

use super::Scene;
use crate::gpu::timer::PassQueries;
use crate::gpu::GpuContext;
use crate::stages::strand_raster::SegRec;
use wgpu::util::DeviceExt;

/// Whether the compute path draws this scene: 4 samples, strands to draw, buffers within
/// the device's limits, and edge values that fit the shader's wrapping i32. A row span
/// visits samples within (width + 4) px of a long side and within the segment's length of
/// a cap, so every value it evaluates is below (longest segment + width) · (width + 4) ·
/// 256² in magnitude; the longest segment is the guard band's diagonal.
pub fn usable(ctx: &GpuContext, s: &Scene) -> bool {
    let c = &s.cfg;
    if c.samples != 4 || s.segs.is_empty() {
        return false;
    }
    let width = 2.0 * c.half_width as f64;
    let guard = 16.0 + 2.0 * width;
    let diag = (c.width as f64 + 2.0 * guard).hypot(c.height as f64 + 2.0 * guard);
    let edge_ok = (diag + width) * (width + 4.0) * 65536.0 < (1u64 << 31) as f64;
    let px = c.width as u64 * c.height as u64;
    let limit = ctx.max_binding_bytes();
    // The largest buffer: 4 samples of 8 B colour per pixel.
    edge_ok && px * 32 <= limit
}

struct Layouts {
    zinit: wgpu::BindGroupLayout,
    walk: wgpu::BindGroupLayout,
    colour: wgpu::BindGroupLayout,
    resolve: wgpu::BindGroupLayout,
}

#[derive(Clone, Copy)]
enum Kind {
    Uniform,
    Read,
    ReadWrite,
    Photo,
    MsaaColor,
    MsaaDepth,
}

fn layout(d: &wgpu::Device, label: &str, entries: &[(u32, Kind)]) -> wgpu::BindGroupLayout {
    let buffer = |ty| wgpu::BindingType::Buffer {
        ty,
        has_dynamic_offset: false,
        min_binding_size: None,
    };
    let texture = |sample_type, multisampled| wgpu::BindingType::Texture {
        sample_type,
        view_dimension: wgpu::TextureViewDimension::D2,
        multisampled,
    };
    let unfilterable = wgpu::TextureSampleType::Float { filterable: false };
    let entries: Vec<wgpu::BindGroupLayoutEntry> = entries
        .iter()
        .map(|&(binding, kind)| wgpu::BindGroupLayoutEntry {
            binding,
            visibility: wgpu::ShaderStages::COMPUTE,
            ty: match kind {
                Kind::Uniform => buffer(wgpu::BufferBindingType::Uniform),
                Kind::Read => buffer(wgpu::BufferBindingType::Storage { read_only: true }),
                Kind::ReadWrite => buffer(wgpu::BufferBindingType::Storage { read_only: false }),
                Kind::Photo => texture(unfilterable, false),
                Kind::MsaaColor => texture(unfilterable, true),
                Kind::MsaaDepth => texture(wgpu::TextureSampleType::Depth, true),
            },
            count: None,
        })
        .collect();
    d.create_bind_group_layout(&wgpu::BindGroupLayoutDescriptor {
        label: Some(label),
        entries: &entries,
    })
}

fn layouts(d: &wgpu::Device) -> Layouts {
    use Kind::*;
    Layouts {
        zinit: layout(
            d,
            "strand_vis.zinit",
            &[
                (0, Uniform),
                (8, MsaaDepth),
                (10, ReadWrite),
                (12, ReadWrite),
            ],
        ),
        walk: layout(
            d,
            "strand_vis.walk",
            &[
                (0, Uniform),
                (1, Read),
                (3, Uniform),
                (4, ReadWrite),
                (5, ReadWrite),
                (10, ReadWrite),
                (13, ReadWrite),
            ],
        ),
        colour: layout(
            d,
            "strand_vis.colour",
            &[
                (0, Uniform),
                (1, Read),
                (2, Photo),
                (3, Uniform),
                (6, ReadWrite),
                (11, Read),
                (12, ReadWrite),
            ],
        ),
        resolve: layout(
            d,
            "strand_vis.resolve",
            &[
                (0, Uniform),
                (6, ReadWrite),
                (7, MsaaColor),
                (9, ReadWrite),
                (12, ReadWrite),
            ],
        ),
    }
}

fn pipeline(
    d: &wgpu::Device,
    module: &wgpu::ShaderModule,
    layout: &wgpu::BindGroupLayout,
    entry: &str,
) -> wgpu::ComputePipeline {
    let pl = d.create_pipeline_layout(&wgpu::PipelineLayoutDescriptor {
        label: Some(entry),
        bind_group_layouts: &[Some(layout)],
        immediate_size: 0,
    });
    d.create_compute_pipeline(&wgpu::ComputePipelineDescriptor {
        label: Some(entry),
        layout: Some(&pl),
        module,
        entry_point: Some(entry),
        compilation_options: Default::default(),
        cache: None,
    })
}

fn group(
    d: &wgpu::Device,
    label: &str,
    layout: &wgpu::BindGroupLayout,
    entries: &[(u32, wgpu::BindingResource)],
) -> wgpu::BindGroup {
    let entries: Vec<wgpu::BindGroupEntry> = entries
        .iter()
        .map(|(binding, resource)| wgpu::BindGroupEntry {
            binding: *binding,
            resource: resource.clone(),
        })
        .collect();
    d.create_bind_group(&wgpu::BindGroupDescriptor {
        label: Some(label),
        layout,
        entries: &entries,
    })
}

/// Each chunk of `per` segments in the order the walks run them, with each one's index
/// within its chunk in `local`; and per chunk, where each segment went. The order is by
/// 64 px tile of the first end, then front to back by the nearer end's depth (256
/// levels): most later segments then find their samples already nearer, so `depth`
/// seldom lowers a key and `pick` skips them (`candidate`), while the tile keeps the
/// samples a walk touches close together in memory. Which segment holds a sample is
/// decided by index, not by the order they run in, so the order changes nothing in the
/// image.
fn front_to_back(segs: &[SegRec], per: usize, w: u32, h: u32) -> (Vec<SegRec>, Vec<u32>) {
    const TILE: f32 = 64.0;
    const LEVELS: usize = 256;
    let tiles_x = (w as f32 / TILE).ceil() as usize;
    let tiles = tiles_x * (h as f32 / TILE).ceil() as usize;
    let key = |s: &SegRec| {
        let t = |v: f32, n: usize| ((v / TILE).max(0.0) as usize).min(n - 1);
        let tile = t(s.p0[1], tiles / tiles_x) * tiles_x + t(s.p0[0], tiles_x);
        let z = s.z0.min(s.z1).clamp(0.0, 1.0);
        tile * LEVELS + ((z * LEVELS as f32) as usize).min(LEVELS - 1)
    };
    let mut sorted = Vec::with_capacity(segs.len());
    let mut position = vec![0u32; segs.len()];
    let mut start = vec![0usize; tiles * LEVELS + 1];
    for (c, chunk) in segs.chunks(per).enumerate() {
        start.iter_mut().for_each(|v| *v = 0);
        for s in chunk {
            start[key(s) + 1] += 1;
        }
        for k in 1..start.len() {
            start[k] += start[k - 1];
        }
        let first = sorted.len();
        sorted.resize(first + chunk.len(), chunk[0]);
        for (i, s) in chunk.iter().enumerate() {
            let k = key(s);
            let at = start[k];
            start[k] += 1;
            sorted[first + at] = SegRec {
                local: i as u32,
                ..*s
            };
            position[c * per + i] = at as u32;
        }
    }
    (sorted, position)
}

/// The WGSL `Chunk`.
#[repr(C)]
#[derive(Clone, Copy, bytemuck::Pod, bytemuck::Zeroable)]
struct Chunk {
    base: u32,
    count: u32,
    row: u32,
    _pad: u32,
}

const WALK_GROUP: u32 = 64;

/// Workgroups for `count` segments (x at most 65535) and the invocations per row.
fn walk_groups(count: u32) -> ([u32; 2], u32) {
    let groups = count.div_ceil(WALK_GROUP).max(1);
    let x = groups.min(65535);
    ([x, groups.div_ceil(x)], x * WALK_GROUP)
}

/// Records the five passes into `encoder` (their pipelines built once per device, from the
/// module `module` makes) and returns the buffer of resolved pixels
/// (`width · height` linear premultiplied RGBA in f16, rows unpadded, as the render
/// pipeline's resolve target holds them).
#[allow(clippy::too_many_arguments)]
pub fn encode(
    ctx: &GpuContext,
    module: impl FnOnce() -> wgpu::ShaderModule,
    s: &Scene,
    encoder: &mut wgpu::CommandEncoder,
    mut queries: Option<&mut PassQueries>,
    uniform: &wgpu::Buffer,
    chunk_bytes: u64,
    color: &wgpu::TextureView,
    depth: &wgpu::TextureView,
) -> wgpu::Buffer {
    let d = &ctx.device;
    let (w, h) = (s.cfg.width, s.cfg.height);
    let px = w as u64 * h as u64;
    let kept = ctx.cached("strand_vis", || {
        let l = layouts(d);
        let module = module();
        let p = |layout: &wgpu::BindGroupLayout, entry: &str| pipeline(d, &module, layout, entry);
        let pipes = [
            p(&l.zinit, "zinit"),
            p(&l.walk, "depth"),
            p(&l.walk, "pick"),
            p(&l.colour, "colour"),
            p(&l.resolve, "resolve"),
        ];
        (l, pipes)
    });
    let (l, pipes) = (&kept.0, &kept.1);
    let storage = |label: &str, size: u64| {
        d.create_buffer(&wgpu::BufferDescriptor {
            label: Some(label),
            size,
            usage: wgpu::BufferUsages::STORAGE | wgpu::BufferUsages::COPY_SRC,
            mapped_at_creation: false,
        })
    };
    // Per pixel: 4 samples of depth key and holder (u32 each), of colour (2 x u32); and
    // the resolved RGBA in f16.
    let zbuf = storage("strand_vis.zbuf", px * 16);
    let ibuf = storage("strand_vis.ibuf", px * 16);
    let cbuf = storage("strand_vis.cbuf", px * 32);
    let out = storage("strand_vis.resolved", px * 8);
    let photo = super::texture_rgba32_or_blank(ctx, s.photo.as_ref());

    let per = super::per_chunk::<SegRec>(chunk_bytes);
    let (sorted, position) = front_to_back(&s.segs, per, w, h);
    let chunks = super::chunks(ctx, "strand_vis.segs", &sorted, chunk_bytes);
    let position: Vec<wgpu::Buffer> = position
        .chunks(per)
        .map(|c| {
            d.create_buffer_init(&wgpu::util::BufferInitDescriptor {
                label: Some("strand_vis.position"),
                contents: bytemuck::cast_slice(c),
                usage: wgpu::BufferUsages::STORAGE,
            })
        })
        .collect();
    let mut base = 0u32;
    let per_chunk: Vec<(wgpu::BindGroup, wgpu::BindGroup, [u32; 2])> = chunks
        .iter()
        .zip(&position)
        .map(|((buf, count), position)| {
            let (groups, row) = walk_groups(*count);
            let c = Chunk {
                base,
                count: *count,
                row,
                _pad: 0,
            };
            base += count;
            let cu = d.create_buffer_init(&wgpu::util::BufferInitDescriptor {
                label: Some("strand_vis.chunk"),
                contents: bytemuck::bytes_of(&c),
                usage: wgpu::BufferUsages::UNIFORM,
            });
            // Zeroed at creation, as wgpu clears every new buffer.
            let candidate = storage("strand_vis.candidate", *count as u64 * 4);
            let walk = group(
                d,
                "strand_vis.walk",
                &l.walk,
                &[
                    (0, uniform.as_entire_binding()),
                    (1, buf.as_entire_binding()),
                    (3, cu.as_entire_binding()),
                    (4, zbuf.as_entire_binding()),
                    (5, ibuf.as_entire_binding()),
                    (10, zbuf.as_entire_binding()),
                    (13, candidate.as_entire_binding()),
                ],
            );
            let colour = group(
                d,
                "strand_vis.colour",
                &l.colour,
                &[
                    (0, uniform.as_entire_binding()),
                    (1, buf.as_entire_binding()),
                    (2, wgpu::BindingResource::TextureView(&photo)),
                    (3, cu.as_entire_binding()),
                    (6, cbuf.as_entire_binding()),
                    (11, position.as_entire_binding()),
                    (12, ibuf.as_entire_binding()),
                ],
            );
            (walk, colour, groups)
        })
        .collect();
    let zinit = group(
        d,
        "strand_vis.zinit",
        &l.zinit,
        &[
            (0, uniform.as_entire_binding()),
            (8, wgpu::BindingResource::TextureView(depth)),
            (10, zbuf.as_entire_binding()),
            (12, ibuf.as_entire_binding()),
        ],
    );
    let resolve = group(
        d,
        "strand_vis.resolve",
        &l.resolve,
        &[
            (0, uniform.as_entire_binding()),
            (6, cbuf.as_entire_binding()),
            (7, wgpu::BindingResource::TextureView(color)),
            (9, out.as_entire_binding()),
            (12, ibuf.as_entire_binding()),
        ],
    );
    let pixels = [w.div_ceil(8), h.div_ceil(8)];
    // One compute pass per step: every chunk's dispatch of a step before any of the next.
    let labels = [
        "strand_vis.zinit",
        "strand_vis.depth",
        "strand_vis.pick",
        "strand_vis.colour",
        "strand_vis.resolve",
    ];
    for (step, (label, p)) in labels.into_iter().zip(pipes).enumerate() {
        let mut pass = encoder.begin_compute_pass(&wgpu::ComputePassDescriptor {
            label: Some(label),
            timestamp_writes: queries.as_mut().map(|q| q.compute(label)),
        });
        pass.set_pipeline(p);
        match step {
            0 => {
                pass.set_bind_group(0, &zinit, &[]);
                pass.dispatch_workgroups(pixels[0], pixels[1], 1);
            }
            4 => {
                pass.set_bind_group(0, &resolve, &[]);
                pass.dispatch_workgroups(pixels[0], pixels[1], 1);
            }
            3 => {
                for (_, colour, _) in &per_chunk {
                    pass.set_bind_group(0, colour, &[]);
                    pass.dispatch_workgroups(pixels[0], pixels[1], 1);
                }
            }
            _ => {
                for (walk, _, groups) in &per_chunk {
                    pass.set_bind_group(0, walk, &[]);
                    pass.dispatch_workgroups(groups[0], groups[1], 1);
                }
            }
        }
    }
    out
}

#[cfg(test)]
mod tests {
    use super::*;

    fn seg(x: f32, y: f32, z: f32) -> SegRec {
        SegRec {
            p0: [x, y],
            p1: [x + 3.0, y + 1.0],
            z0: z,
            z1: z + 0.01,
            strand: 0,
            local: 0,
            c0: [1.0; 4],
            c1: [1.0; 4],
            o: [0.0; 4],
        }
    }

    /// Per chunk: a permutation whose `local` is the input index and whose `position` is its
    /// inverse, ordered by tile, then nearer depth first.
    #[test]
    fn front_to_back_permutes_each_chunk_and_records_the_way_back() {
        let mut rng = crate::base::rng::Rng::new(3);
        let segs: Vec<SegRec> = (0..1000)
            .map(|_| {
                seg(
                    rng.next_f32() * 300.0 - 20.0,
                    rng.next_f32() * 200.0,
                    rng.next_f32() * 1.2 - 0.1,
                )
            })
            .collect();
        let per = 300;
        let (sorted, position) = front_to_back(&segs, per, 256, 192);
        assert_eq!(sorted.len(), segs.len());
        for (c, chunk) in segs.chunks(per).enumerate() {
            let out = &sorted[c * per..c * per + chunk.len()];
            let back = &position[c * per..c * per + chunk.len()];
            for (i, s) in chunk.iter().enumerate() {
                let at = out[back[i] as usize];
                assert_eq!(at.local as usize, i);
                assert_eq!(SegRec { local: 0, ..at }, *s);
            }
            let key = |s: &SegRec| {
                let tile = |v: f32, n: f32| (v / 64.0).max(0.0).min(n - 1.0).floor();
                (
                    tile(s.p0[1], 3.0) * 4.0 + tile(s.p0[0], 4.0),
                    s.z0.min(s.z1),
                )
            };
            for pair in out.windows(2) {
                let (a, b) = (key(&pair[0]), key(&pair[1]));
                assert!(a.0 <= b.0, "tiles out of order");
                // Within a tile, by 256 depth levels: never more than a level backwards.
                if a.0 == b.0 {
                    assert!(b.1.clamp(0.0, 1.0) >= a.1.clamp(0.0, 1.0) - 1.0 / 256.0);
                }
            }
        }
    }

    #[test]
    fn walk_groups_cover_every_segment_within_the_dispatch_limit() {
        for count in [1u32, 63, 64, 65, 65535 * 64, 65535 * 64 + 1, 10_000_000] {
            let ([x, y], row) = walk_groups(count);
            assert!(x <= 65535 && y <= 65535, "{count}");
            assert_eq!(row, x * WALK_GROUP);
            assert!(
                x as u64 * y as u64 * WALK_GROUP as u64 >= count as u64,
                "{count}"
            );
        }
    }
}
