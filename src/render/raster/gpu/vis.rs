//! The strands as compute passes (`wgsl/render/strand_vis.wgsl`, whose header gives the
//! passes and why, or `strand_vis64.wgsl`, its depth and pick in one walk, where the device
//! has 64-bit atomics): used for 4x MSAA frames with strands, after the render pipelines
//! have drawn the background and the mesh into a stored MSAA target.

use super::Scene;
use crate::gpu::engine::RenderStageDef;
use crate::gpu::pool::Pooled;
use crate::gpu::timer::PassQueries;
use crate::gpu::GpuContext;
use crate::stages::strand_raster::{self, SegRec};
use rayon::prelude::*;
use wgpu::util::DeviceExt;

/// The compute strand stage a device runs: one walk with 64-bit atomics where it has them
/// (unless `two_walks` asks for the other, as tests do), else depth and pick in two walks.
pub fn stage(ctx: &GpuContext, two_walks: bool) -> &'static RenderStageDef {
    if ctx.has_int64_atomics() && !two_walks {
        &strand_raster::VIS64
    } else {
        &strand_raster::VIS
    }
}

/// Whether the compute path draws this scene: 4 samples, strands to draw, buffers within
/// the device's limits, and edge values that fit the shader's wrapping i32. A row span
/// visits samples within (width + 4) px of a long side and within the segment's length of
/// a cap, so every value it evaluates is below (longest segment + width) · (width + 4) ·
/// 256² in magnitude; the longest segment is the guard band's diagonal.
pub fn usable(ctx: &GpuContext, s: &Scene) -> bool {
    let c = &s.cfg;
    if c.samples != 4 || s.drawn.is_empty() {
        return false;
    }
    let width = 2.0 * c.half_width as f64;
    let guard = 16.0 + 2.0 * width;
    let diag = (c.width as f64 + 2.0 * guard).hypot(c.height as f64 + 2.0 * guard);
    let edge_ok = (diag + width) * (width + 4.0) * 65536.0 < (1u64 << 31) as f64;
    let px = c.width as u64 * c.height as u64;
    let limit = ctx.max_binding_bytes();
    // The largest buffers: 4 samples of 8 B colour (and of 8 B visibility, `strand_vis64`)
    // per pixel.
    edge_ok && px * 32 <= limit
}

struct Layouts {
    zinit: wgpu::BindGroupLayout,
    walk: wgpu::BindGroupLayout,
    colour: wgpu::BindGroupLayout,
    resolve: wgpu::BindGroupLayout,
    shade: wgpu::BindGroupLayout,
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

/// The layouts of the two stages: `strand_vis` keeps holders apart (ibuf 5, its plain view
/// 12, the candidate flags 13), `strand_vis64` holds them in zbuf's low words, so its colour
/// and resolve read zbuf's plain view (10).
fn layouts(d: &wgpu::Device, wide: bool) -> Layouts {
    use Kind::*;
    let holders = if wide { 10 } else { 12 };
    let walk: &[(u32, Kind)] = if wide {
        &[
            (0, Uniform),
            (1, Read),
            (3, Uniform),
            (4, ReadWrite),
            (10, ReadWrite),
        ]
    } else {
        &[
            (0, Uniform),
            (1, Read),
            (3, Uniform),
            (4, ReadWrite),
            (5, ReadWrite),
            (10, ReadWrite),
            (13, ReadWrite),
        ]
    };
    let zinit: &[(u32, Kind)] = if wide {
        &[(0, Uniform), (8, MsaaDepth), (10, ReadWrite)]
    } else {
        &[
            (0, Uniform),
            (8, MsaaDepth),
            (10, ReadWrite),
            (12, ReadWrite),
        ]
    };
    Layouts {
        zinit: layout(d, "strand_vis.zinit", zinit),
        walk: layout(d, "strand_vis.walk", walk),
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
                (holders, ReadWrite),
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
                (holders, ReadWrite),
            ],
        ),
        shade: layout(
            d,
            "strand_vis.shade",
            &[
                (0, Uniform),
                (1, Read),
                (2, Photo),
                (3, Uniform),
                (7, MsaaColor),
                (9, ReadWrite),
                (11, Read),
                (holders, ReadWrite),
            ],
        ),
    }
}

fn pipeline(
    d: &wgpu::Device,
    module: &wgpu::ShaderModule,
    layout: &wgpu::BindGroupLayout,
    entry: &str,
    constants: &[(&str, f64)],
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
        compilation_options: wgpu::PipelineCompilationOptions {
            constants,
            ..Default::default()
        },
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

/// The order the walks run a chunk's `n` segments in: `order[slot]` is the input index of
/// the segment in that slot and `position[i]` the slot of input index i. By 64 px tile of the
/// first end, then front to back by the nearer end's depth (256 levels), both as `ends(i)`
/// gives them (the raw end points, before clipping, will do): most later segments
/// then find their samples already nearer, so `depth` seldom lowers a key (and `pick` skips
/// them, `candidate`), while the tile keeps the samples a walk touches close together in
/// memory. Which segment holds a sample is decided by index, not by the order they run in,
/// so the order changes nothing in the image. A counting sort of indices, stable; the keys
/// in parallel.
fn front_to_back(
    n: usize,
    ends: impl Fn(usize) -> ([f32; 2], f32) + Sync,
    w: u32,
    h: u32,
) -> (Vec<u32>, Vec<u32>) {
    const TILE: f32 = 64.0;
    const LEVELS: usize = 256;
    let tiles_x = (w as f32 / TILE).ceil() as usize;
    let tiles = tiles_x * (h as f32 / TILE).ceil() as usize;
    let keys: Vec<u32> = (0..n)
        .into_par_iter()
        .map(|i| {
            let (p0, z) = ends(i);
            let t = |v: f32, n: usize| ((v / TILE).max(0.0) as usize).min(n - 1);
            let tile = t(p0[1], tiles / tiles_x) * tiles_x + t(p0[0], tiles_x);
            // (A NaN depth clamps to 0 here: the order only needs a key.)
            let z = z.clamp(0.0, 1.0);
            (tile * LEVELS + ((z * LEVELS as f32) as usize).min(LEVELS - 1)) as u32
        })
        .collect();
    let mut start = vec![0u32; tiles * LEVELS + 1];
    for &k in &keys {
        start[k as usize + 1] += 1;
    }
    for k in 1..start.len() {
        start[k] += start[k - 1];
    }
    let mut order = vec![0u32; n];
    let mut position = vec![0u32; n];
    for (i, &k) in keys.iter().enumerate() {
        let at = start[k as usize];
        start[k as usize] += 1;
        order[at as usize] = i as u32;
        position[i] = at;
    }
    (order, position)
}

/// A storage buffer of `size` bytes that `fill` writes whole through a mapping: on a CPU
/// driver ([`GpuContext::maps_storage`]) the mapping is the buffer itself, one the pool
/// kept from the previous call of this size (none of its old bytes survive `fill`),
/// elsewhere a new buffer's staging memory that wgpu copies from. The buffer, and the pool's
/// hold on it when it has one (dropped when the GPU is done with it).
fn filled_storage<'a>(
    ctx: &'a GpuContext,
    label: &'static str,
    size: u64,
    fill: impl FnOnce(&mut wgpu::BufferViewMut),
) -> (wgpu::Buffer, Option<Pooled<'a, wgpu::Buffer>>) {
    let map_failed = "a storage buffer for the strands cannot be mapped";
    if !ctx.maps_storage() {
        let buf = ctx.device.create_buffer(&wgpu::BufferDescriptor {
            label: Some(label),
            size,
            usage: wgpu::BufferUsages::STORAGE,
            mapped_at_creation: true,
        });
        fill(&mut buf.slice(..).get_mapped_range_mut().expect(map_failed));
        buf.unmap();
        return (buf, None);
    }
    let usage = wgpu::BufferUsages::STORAGE | wgpu::BufferUsages::MAP_WRITE;
    let mut pooled = ctx.buffer(label, size, usage);
    let (tx, rx) = std::sync::mpsc::channel();
    pooled
        .slice(..)
        .map_async(wgpu::MapMode::Write, move |r| drop(tx.send(r)));
    // The buffer's last use was a render already waited for, so the map completes in this
    // poll; but when threads share the device another thread's poll may be the one running
    // the callback, and ours may return before it has sent: wait for the message, not just
    // for the poll (a `try_recv` here failed a test now and then under a full test run).
    let ready = ctx
        .device
        .poll(wgpu::PollType::wait_indefinitely())
        .ok()
        .and_then(|_| rx.recv_timeout(std::time::Duration::from_secs(60)).ok())
        .is_some_and(|r| r.is_ok());
    assert!(ready, "{map_failed}");
    fill(&mut pooled.slice(..).get_mapped_range_mut().expect(map_failed));
    pooled.unmap();
    ((*pooled).clone(), Some(pooled))
}

/// A storage buffer holding the segments `chunk` of `s`'s drawn list in `order`, each
/// prepared ([`Scene::seg_rec`]) with its `local` set to its input index, in parallel
/// straight into the buffer's mapping ([`filled_storage`]; prepared into a vector first,
/// then gathered, cost as much again, in page faults and copies of 118 MB).
fn upload_ordered<'a>(
    ctx: &'a GpuContext,
    s: &Scene,
    chunk: &[[u32; 2]],
    order: &[u32],
) -> (wgpu::Buffer, Option<Pooled<'a, wgpu::Buffer>>) {
    const SIZE: usize = std::mem::size_of::<SegRec>();
    filled_storage(
        ctx,
        "strand_vis.segs",
        (order.len() * SIZE) as u64,
        |view| {
            let mut out = view.slice(..);
            assert_eq!(out.len(), order.len() * SIZE);
            /// The mapping's start, shared by the gather's threads.
            struct Out(std::ptr::NonNull<u8>);
            // SAFETY: the threads write disjoint slots only (their own byte ranges), and the
            // mapping outlives the gather.
            unsafe impl Sync for Out {}
            let base = Out(out.as_raw_element_ptr());
            const PIECE: usize = 4096;
            order
                .par_chunks(PIECE)
                .enumerate()
                .for_each(|(piece, idx)| {
                    let base = &base;
                    for (j, &i) in idx.iter().enumerate() {
                        let rec = SegRec {
                            local: i,
                            ..s.seg_rec(chunk[i as usize])
                        };
                        // SAFETY: slot piece·PIECE + j < order.len(), inside the mapping (checked
                        // above), written by this thread alone; unaligned writes need no alignment
                        // of the mapping; a SegRec is plain data.
                        unsafe {
                            base.0
                                .as_ptr()
                                .add((piece * PIECE + j) * SIZE)
                                .cast::<SegRec>()
                                .write_unaligned(rec);
                        }
                    }
                });
        },
    )
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

/// Records the passes of `stage` (see [`stage`]) into `encoder` (their pipelines built once
/// per device, from the module `module` makes; `mesh_drawn` says whether the render
/// pipelines drew a mesh into `depth`) and returns the buffer of resolved pixels
/// (`width · height` linear premultiplied RGBA in f16, rows unpadded, as the render
/// pipeline's resolve target holds them).
#[allow(clippy::too_many_arguments)]
pub fn encode<'a>(
    ctx: &'a GpuContext,
    stage: &RenderStageDef,
    module: impl FnOnce() -> wgpu::ShaderModule,
    s: &Scene,
    mesh_drawn: bool,
    encoder: &mut wgpu::CommandEncoder,
    mut queries: Option<&mut PassQueries>,
    uniform: &wgpu::Buffer,
    chunk_bytes: u64,
    color: &wgpu::TextureView,
    depth: &wgpu::TextureView,
) -> Encoded<'a> {
    let d = &ctx.device;
    let (w, h) = (s.cfg.width, s.cfg.height);
    let px = w as u64 * h as u64;
    // One walk (`depth`) with 64-bit atomics, else `depth` then `pick`.
    let wide = stage.int64_atomics;
    let kept = ctx.cached(stage.name, || {
        let l = layouts(d, wide);
        let module = module();
        let p =
            |layout: &wgpu::BindGroupLayout, entry: &str| pipeline(d, &module, layout, entry, &[]);
        let walks: Vec<wgpu::ComputePipeline> = if wide {
            vec![p(&l.walk, "depth")]
        } else {
            vec![p(&l.walk, "depth"), p(&l.walk, "pick")]
        };
        let pipes = [
            p(&l.zinit, "zinit"),
            pipeline(d, &module, &l.zinit, "zinit", &[("mesh_drawn", 0.0)]),
            p(&l.colour, "colour"),
            p(&l.resolve, "resolve"),
            p(&l.shade, "shade"),
        ];
        (l, walks, pipes)
    });
    let (l, walks, [zinit_mesh, zinit_bare, colour_pipe, resolve_pipe, shade_pipe]) =
        (&kept.0, &kept.1, &kept.2);
    let zinit_pipe = if mesh_drawn { zinit_mesh } else { zinit_bare };
    // From the pool: every sample of `zbuf` (and `ibuf`) is written by `zinit`, every pixel
    // of `out` by the resolve; a sample of `cbuf` is read only where a segment holds it,
    // after that segment's chunk wrote it. So nothing a previous render left is read.
    let storage = |label: &'static str, size: u64| {
        ctx.buffer(
            label,
            size,
            wgpu::BufferUsages::STORAGE | wgpu::BufferUsages::COPY_SRC,
        )
    };
    // Per pixel, 4 samples of: depth key and holder (u32 each, or one u64), colour
    // (2 x u32); and the resolved RGBA in f16.
    let zbuf = storage("strand_vis.zbuf", px * if wide { 32 } else { 16 });
    let ibuf = (!wide).then(|| storage("strand_vis.ibuf", px * 16));
    // Where colour and resolve find the holders: ibuf, or zbuf's low words.
    let holders: &wgpu::Buffer = ibuf.as_deref().unwrap_or(&zbuf);
    let holders_at = if wide { 10 } else { 12 };
    let out = storage("strand_vis.resolved", px * 8);
    let photo = super::texture_rgba32_or_blank(ctx, s.photo.as_ref());

    let per = super::per_chunk::<SegRec>(chunk_bytes);
    // One chunk (the usual case: a chunk holds the binding limit's worth, 1.6M segments on
    // lavapipe) is coloured and resolved in one pass (`shade`); more need the per-sample
    // colour buffer between a colour pass per chunk and the resolve.
    let one_chunk = s.drawn.len() <= per;
    let cbuf = storage("strand_vis.cbuf", if one_chunk { 8 } else { px * 32 });
    let mut base = 0u32;
    let mut held = Vec::new();
    let per_chunk: Vec<(wgpu::BindGroup, wgpu::BindGroup, wgpu::BindGroup, [u32; 2])> = s
        .drawn
        .chunks(per)
        .map(|segs| {
            let count = segs.len() as u32;
            let (order, position) = front_to_back(segs.len(), |i| s.order_ends(segs[i]), w, h);
            let (buf, buf_pooled) = upload_ordered(ctx, s, segs, &order);
            let (position, position_pooled) = filled_storage(
                ctx,
                "strand_vis.position",
                (position.len() * 4) as u64,
                |view| view.copy_from_slice(bytemuck::cast_slice(&position)),
            );
            held.extend(buf_pooled.into_iter().chain(position_pooled));
            let (groups, row) = walk_groups(count);
            let c = Chunk {
                base,
                count,
                row,
                _pad: 0,
            };
            base += count;
            let cu = d.create_buffer_init(&wgpu::util::BufferInitDescriptor {
                label: Some("strand_vis.chunk"),
                contents: bytemuck::bytes_of(&c),
                usage: wgpu::BufferUsages::UNIFORM,
            });
            let mut walk = vec![
                (0, uniform.as_entire_binding()),
                (1, buf.as_entire_binding()),
                (3, cu.as_entire_binding()),
                (4, zbuf.as_entire_binding()),
                (10, zbuf.as_entire_binding()),
            ];
            // Zeroed at creation, as wgpu clears every new buffer (so not from the pool).
            let candidate = (!wide).then(|| {
                d.create_buffer(&wgpu::BufferDescriptor {
                    label: Some("strand_vis.candidate"),
                    size: count as u64 * 4,
                    usage: wgpu::BufferUsages::STORAGE,
                    mapped_at_creation: false,
                })
            });
            if let (Some(ibuf), Some(candidate)) = (&ibuf, &candidate) {
                walk.push((5, ibuf.as_entire_binding()));
                walk.push((13, candidate.as_entire_binding()));
            }
            let walk = group(d, "strand_vis.walk", &l.walk, &walk);
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
                    (holders_at, holders.as_entire_binding()),
                ],
            );
            let shade = group(
                d,
                "strand_vis.shade",
                &l.shade,
                &[
                    (0, uniform.as_entire_binding()),
                    (1, buf.as_entire_binding()),
                    (2, wgpu::BindingResource::TextureView(&photo)),
                    (3, cu.as_entire_binding()),
                    (7, wgpu::BindingResource::TextureView(color)),
                    (9, out.as_entire_binding()),
                    (11, position.as_entire_binding()),
                    (holders_at, holders.as_entire_binding()),
                ],
            );
            (walk, colour, shade, groups)
        })
        .collect();
    let mut zinit = vec![
        (0, uniform.as_entire_binding()),
        (8, wgpu::BindingResource::TextureView(depth)),
        (10, zbuf.as_entire_binding()),
    ];
    if let Some(ibuf) = &ibuf {
        zinit.push((12, ibuf.as_entire_binding()));
    }
    let zinit = group(d, "strand_vis.zinit", &l.zinit, &zinit);
    let resolve = group(
        d,
        "strand_vis.resolve",
        &l.resolve,
        &[
            (0, uniform.as_entire_binding()),
            (6, cbuf.as_entire_binding()),
            (7, wgpu::BindingResource::TextureView(color)),
            (9, out.as_entire_binding()),
            (holders_at, holders.as_entire_binding()),
        ],
    );
    let pixels = [w.div_ceil(8), h.div_ceil(8)];
    // One compute pass per step: every chunk's dispatch of a step before any of the next.
    enum Step<'a> {
        // Once, per pixel.
        Frame(&'a wgpu::BindGroup),
        // Per chunk, per segment.
        Walk,
        // Per chunk, per pixel.
        Colour,
    }
    let walk_labels = ["strand_vis.depth", "strand_vis.pick"];
    let last: Vec<(&str, &wgpu::ComputePipeline, Step)> = if one_chunk {
        vec![("strand_vis.shade", shade_pipe, Step::Frame(&per_chunk[0].2))]
    } else {
        vec![
            ("strand_vis.colour", colour_pipe, Step::Colour),
            ("strand_vis.resolve", resolve_pipe, Step::Frame(&resolve)),
        ]
    };
    let steps = std::iter::once(("strand_vis.zinit", zinit_pipe, Step::Frame(&zinit)))
        .chain(
            walk_labels
                .into_iter()
                .zip(walks)
                .map(|(l, p)| (l, p, Step::Walk)),
        )
        .chain(last);
    for (label, p, step) in steps {
        let mut pass = encoder.begin_compute_pass(&wgpu::ComputePassDescriptor {
            label: Some(label),
            timestamp_writes: queries.as_mut().map(|q| q.compute(label)),
        });
        pass.set_pipeline(p);
        match step {
            Step::Frame(g) => {
                pass.set_bind_group(0, g, &[]);
                pass.dispatch_workgroups(pixels[0], pixels[1], 1);
            }
            Step::Walk => {
                for (walk, _, _, groups) in &per_chunk {
                    pass.set_bind_group(0, walk, &[]);
                    pass.dispatch_workgroups(groups[0], groups[1], 1);
                }
            }
            Step::Colour => {
                for (_, colour, _, _) in &per_chunk {
                    pass.set_bind_group(0, colour, &[]);
                    pass.dispatch_workgroups(pixels[0], pixels[1], 1);
                }
            }
        }
    }
    held.extend([zbuf, cbuf].into_iter().chain(ibuf));
    Encoded { out, _held: held }
}

/// What [`encode`] recorded passes into: the buffer of resolved pixels, and the pooled
/// buffers the passes use, to be dropped (given back to the pool) once the encoder is
/// submitted, so that no later request in this render can take and overwrite one first.
pub struct Encoded<'a> {
    pub out: Pooled<'a, wgpu::Buffer>,
    pub _held: Vec<Pooled<'a, wgpu::Buffer>>,
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

    /// A permutation (`order`) with its inverse (`position`), ordered by tile, then nearer
    /// depth first, input order kept among equal keys (the sort is stable).
    #[test]
    fn front_to_back_permutes_and_records_the_way_back() {
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
        let (order, position) = front_to_back(
            segs.len(),
            |i| (segs[i].p0, segs[i].z0.min(segs[i].z1)),
            256,
            192,
        );
        assert_eq!(order.len(), segs.len());
        for (i, &at) in position.iter().enumerate() {
            assert_eq!(order[at as usize] as usize, i);
        }
        let key = |i: u32| {
            let s = &segs[i as usize];
            let tile = |v: f32, n: f32| (v / 64.0).max(0.0).min(n - 1.0).floor();
            let level = (s.z0.min(s.z1).clamp(0.0, 1.0) * 256.0).min(255.0).floor();
            (tile(s.p0[1], 3.0) * 4.0 + tile(s.p0[0], 4.0), level, i)
        };
        for pair in order.windows(2) {
            let (a, b) = (key(pair[0]), key(pair[1]));
            assert!(a < b, "{a:?} before {b:?}");
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
