//! The wgpu host of the render passes ([`crate::stages::RENDER`]): builds the background,
//! mesh and strand pipelines, uploads the prepared scene in chunks that respect the device's
//! binding limit, draws them into one multisampled Rgba16Float target and reads back the
//! resolve. At 4x MSAA the strands are drawn by compute passes instead ([`vis`]), after the
//! background and mesh, when the frame allows it.

use super::{GpuStrands, Scene};
use crate::base::colour::f16_bits_to_f32;
use crate::error::{Error, Result};
use crate::gpu::engine::RenderStageDef;
use crate::gpu::pool::Pooled;
use crate::gpu::GpuContext;
use crate::stages::{mesh_raster, strand_raster};
use rayon::prelude::*;
use wgpu::util::DeviceExt;

mod vis;

const COLOR_FORMAT: wgpu::TextureFormat = wgpu::TextureFormat::Rgba16Float;
const DEPTH_FORMAT: wgpu::TextureFormat = wgpu::TextureFormat::Depth32Float;

/// The source of a registered render stage, its includes expanded.
fn source(stage: &RenderStageDef) -> Result<(&'static str, String)> {
    Ok((
        stage.name,
        crate::gpu::wgsl::compose(stage.name, stage.wgsl)?,
    ))
}

fn module(d: &wgpu::Device, (name, source): (&str, String)) -> wgpu::ShaderModule {
    d.create_shader_module(wgpu::ShaderModuleDescriptor {
        label: Some(name),
        source: wgpu::ShaderSource::Wgsl(source.into()),
    })
}

fn uniform_entry(binding: u32) -> wgpu::BindGroupLayoutEntry {
    wgpu::BindGroupLayoutEntry {
        binding,
        visibility: wgpu::ShaderStages::VERTEX_FRAGMENT,
        ty: wgpu::BindingType::Buffer {
            ty: wgpu::BufferBindingType::Uniform,
            has_dynamic_offset: false,
            min_binding_size: None,
        },
        count: None,
    }
}

fn storage_entry(binding: u32) -> wgpu::BindGroupLayoutEntry {
    wgpu::BindGroupLayoutEntry {
        binding,
        visibility: wgpu::ShaderStages::VERTEX,
        ty: wgpu::BindingType::Buffer {
            ty: wgpu::BufferBindingType::Storage { read_only: true },
            has_dynamic_offset: false,
            min_binding_size: None,
        },
        count: None,
    }
}

fn texture_entry(binding: u32) -> wgpu::BindGroupLayoutEntry {
    wgpu::BindGroupLayoutEntry {
        binding,
        visibility: wgpu::ShaderStages::FRAGMENT,
        ty: wgpu::BindingType::Texture {
            sample_type: wgpu::TextureSampleType::Float { filterable: false },
            view_dimension: wgpu::TextureViewDimension::D2,
            multisampled: false,
        },
        count: None,
    }
}

struct Pipe {
    layout: wgpu::BindGroupLayout,
    pipeline: wgpu::RenderPipeline,
}

#[allow(clippy::too_many_arguments)]
fn pipe(
    d: &wgpu::Device,
    label: &str,
    module: &wgpu::ShaderModule,
    (vs, fs): (&str, &str),
    entries: &[wgpu::BindGroupLayoutEntry],
    topology: wgpu::PrimitiveTopology,
    cull: Option<wgpu::Face>,
    depth_write: bool,
    compare: wgpu::CompareFunction,
    samples: u32,
) -> Pipe {
    let layout = d.create_bind_group_layout(&wgpu::BindGroupLayoutDescriptor {
        label: Some(label),
        entries,
    });
    let pl = d.create_pipeline_layout(&wgpu::PipelineLayoutDescriptor {
        label: Some(label),
        bind_group_layouts: &[Some(&layout)],
        immediate_size: 0,
    });
    let pipeline = d.create_render_pipeline(&wgpu::RenderPipelineDescriptor {
        label: Some(label),
        layout: Some(&pl),
        vertex: wgpu::VertexState {
            module,
            entry_point: Some(vs),
            compilation_options: Default::default(),
            buffers: &[],
        },
        primitive: wgpu::PrimitiveState {
            topology,
            strip_index_format: None,
            front_face: wgpu::FrontFace::Ccw,
            cull_mode: cull,
            unclipped_depth: false,
            polygon_mode: wgpu::PolygonMode::Fill,
            conservative: false,
        },
        depth_stencil: Some(wgpu::DepthStencilState {
            format: DEPTH_FORMAT,
            depth_write_enabled: Some(depth_write),
            depth_compare: Some(compare),
            stencil: Default::default(),
            bias: Default::default(),
        }),
        // Alpha-to-coverage is done by the strand shader itself (deterministic rule).
        multisample: wgpu::MultisampleState {
            count: samples,
            mask: !0,
            alpha_to_coverage_enabled: false,
        },
        fragment: Some(wgpu::FragmentState {
            module,
            entry_point: Some(fs),
            compilation_options: Default::default(),
            targets: &[Some(wgpu::ColorTargetState {
                format: COLOR_FORMAT,
                blend: None,
                write_mask: wgpu::ColorWrites::ALL,
            })],
        }),
        multiview_mask: None,
        cache: None,
    });
    Pipe { layout, pipeline }
}

fn texture_rgba32(
    ctx: &GpuContext,
    label: &str,
    w: u32,
    h: u32,
    texels: &[[f32; 4]],
) -> wgpu::TextureView {
    let size = wgpu::Extent3d {
        width: w,
        height: h,
        depth_or_array_layers: 1,
    };
    let tex = ctx.device.create_texture(&wgpu::TextureDescriptor {
        label: Some(label),
        size,
        mip_level_count: 1,
        sample_count: 1,
        dimension: wgpu::TextureDimension::D2,
        format: wgpu::TextureFormat::Rgba32Float,
        usage: wgpu::TextureUsages::TEXTURE_BINDING | wgpu::TextureUsages::COPY_DST,
        view_formats: &[],
    });
    ctx.queue.write_texture(
        wgpu::TexelCopyTextureInfo {
            texture: &tex,
            mip_level: 0,
            origin: wgpu::Origin3d::ZERO,
            aspect: wgpu::TextureAspect::All,
        },
        bytemuck::cast_slice(texels),
        wgpu::TexelCopyBufferLayout {
            offset: 0,
            bytes_per_row: Some(w * 16),
            rows_per_image: Some(h),
        },
        size,
    );
    tex.create_view(&Default::default())
}

/// The strands' photo; the shader only reads it when `cfg.photo` says so, and a 1x1
/// texture stands in otherwise (the layout needs a binding).
fn texture_rgba32_or_blank(ctx: &GpuContext, t: Option<&super::Texture>) -> wgpu::TextureView {
    match t {
        Some(t) => texture_rgba32(ctx, "raster.photo", t.width, t.height, &t.texels),
        None => texture_rgba32(ctx, "raster.photo", 1, 1, &[[0.0; 4]]),
    }
}

/// A render target from the pool (every render pass clears its targets first, so what a
/// previous render left is never read).
fn target<'a>(
    ctx: &'a GpuContext,
    label: &'static str,
    w: u32,
    h: u32,
    samples: u32,
    format: wgpu::TextureFormat,
    usage: wgpu::TextureUsages,
) -> Pooled<'a, wgpu::Texture> {
    let size = wgpu::Extent3d {
        width: w,
        height: h,
        depth_or_array_layers: 1,
    };
    ctx.texture(label, size, samples, format, usage)
}

/// Storage buffers of at most `chunk_bytes` each, with their item counts.
/// Items per chunk of at most `chunk_bytes` (what [`chunks`] puts in each).
fn per_chunk<T>(chunk_bytes: u64) -> usize {
    // A mesh chunk draws 3 vertices per item, a strand chunk one instance per item: both
    // counts must fit a u32.
    (chunk_bytes / std::mem::size_of::<T>() as u64).clamp(1, u32::MAX as u64 / 3) as usize
}

fn chunks<T: bytemuck::Pod>(
    ctx: &GpuContext,
    label: &str,
    items: &[T],
    chunk_bytes: u64,
) -> Vec<(wgpu::Buffer, u32)> {
    items
        .chunks(per_chunk::<T>(chunk_bytes))
        .map(|c| {
            let buf = ctx
                .device
                .create_buffer_init(&wgpu::util::BufferInitDescriptor {
                    label: Some(label),
                    contents: bytemuck::cast_slice(c),
                    usage: wgpu::BufferUsages::STORAGE,
                });
            (buf, c.len() as u32)
        })
        .collect()
}

/// One bind group per chunk of `items` (see [`chunks`]): the uniform, the chunk and `view`,
/// at bindings 0, 1 and 2 as both render shaders declare them.
#[allow(clippy::too_many_arguments)]
fn bind_chunks<T: bytemuck::Pod>(
    ctx: &GpuContext,
    p: &Pipe,
    label: &str,
    uniform: &wgpu::Buffer,
    items: &[T],
    chunk_bytes: u64,
    view: &wgpu::TextureView,
) -> Vec<(wgpu::BindGroup, u32)> {
    chunks(ctx, label, items, chunk_bytes)
        .into_iter()
        .map(|(buf, count)| {
            let bg = ctx.device.create_bind_group(&wgpu::BindGroupDescriptor {
                label: Some(label),
                layout: &p.layout,
                entries: &[
                    wgpu::BindGroupEntry {
                        binding: 0,
                        resource: uniform.as_entire_binding(),
                    },
                    wgpu::BindGroupEntry {
                        binding: 1,
                        resource: buf.as_entire_binding(),
                    },
                    wgpu::BindGroupEntry {
                        binding: 2,
                        resource: wgpu::BindingResource::TextureView(view),
                    },
                ],
            });
            (bg, count)
        })
        .collect()
}

/// The stage that draws this scene's strands when `path` is asked for: the compute passes
/// where the frame allows them (one walk with 64-bit atomics where the device has them, two
/// walks where not or where `path` asks), else the render pipeline.
pub fn strand_stage(ctx: &GpuContext, s: &Scene, path: GpuStrands) -> &'static RenderStageDef {
    if path == GpuStrands::Pipeline || !vis::usable(ctx, s) {
        &strand_raster::STAGE
    } else {
        vis::stage(ctx, path == GpuStrands::TwoWalks)
    }
}

/// Renders the scene, its strands by the path [`strand_stage`] picks for `path`.
pub fn raster(
    ctx: &GpuContext,
    s: &Scene,
    max_chunk_bytes: u64,
    path: GpuStrands,
) -> Result<Vec<[f32; 4]>> {
    let d = &ctx.device;
    let (w, h, n) = (s.cfg.width, s.cfg.height, s.cfg.samples);
    let bytes_per_row = (w * 8).next_multiple_of(wgpu::COPY_BYTES_PER_ROW_ALIGNMENT);
    let readback_bytes = bytes_per_row as u64 * h as u64;
    if readback_bytes > ctx.limits.max_buffer_size {
        return Err(Error::TooLarge {
            what: format!("read-back of a {w}x{h} frame"),
            needed: readback_bytes,
            limit: ctx.limits.max_buffer_size,
            limit_name: "largest buffer".into(),
            unit: "bytes",
        });
    }
    let chunk_bytes = ctx.max_binding_bytes().min(max_chunk_bytes);
    // Composed before the error scopes open, so an early return leaves none behind.
    let (strand_src, mesh_src) = (source(&strand_raster::STAGE)?, source(&mesh_raster::STAGE)?);
    let strand_stage = strand_stage(ctx, s, path);
    let vis = strand_stage.name != strand_raster::STAGE.name;
    let vis_src = if vis {
        Some(source(strand_stage)?)
    } else {
        None
    };
    let validation = d.push_error_scope(wgpu::ErrorFilter::Validation);
    let oom = d.push_error_scope(wgpu::ErrorFilter::OutOfMemory);

    let mesh_module = module(d, mesh_src);
    let less = wgpu::CompareFunction::Less;
    let mut ub = encase::UniformBuffer::new(Vec::<u8>::new());
    ub.write(&s.cfg).expect("uniform fits in memory");
    let uniform = d.create_buffer_init(&wgpu::util::BufferInitDescriptor {
        label: Some("raster.config"),
        contents: &ub.into_inner(),
        usage: wgpu::BufferUsages::UNIFORM,
    });

    let msaa = n > 1;
    let attach = wgpu::TextureUsages::RENDER_ATTACHMENT;
    // The compute strand passes read the background and mesh samples back.
    let sampled = if vis {
        wgpu::TextureUsages::TEXTURE_BINDING
    } else {
        wgpu::TextureUsages::empty()
    };
    let color = target(
        ctx,
        "raster.color",
        w,
        h,
        n,
        COLOR_FORMAT,
        if msaa {
            attach | sampled
        } else {
            attach | wgpu::TextureUsages::COPY_SRC
        },
    );
    let resolve = (msaa && !vis).then(|| {
        target(
            ctx,
            "raster.resolve",
            w,
            h,
            1,
            COLOR_FORMAT,
            attach | wgpu::TextureUsages::COPY_SRC,
        )
    });
    let depth = target(ctx, "raster.depth", w, h, n, DEPTH_FORMAT, attach | sampled);
    let color_view = color.create_view(&Default::default());
    let resolve_view = resolve.as_ref().map(|t| t.create_view(&Default::default()));
    let depth_view = depth.create_view(&Default::default());

    // Background: one bind group, one full-screen triangle.
    let background = s.background.as_ref().map(|bg| {
        let p = pipe(
            d,
            "raster.background",
            &mesh_module,
            mesh_raster::BACKGROUND,
            &[texture_entry(2)],
            wgpu::PrimitiveTopology::TriangleList,
            None,
            false,
            wgpu::CompareFunction::Always,
            n,
        );
        let view = texture_rgba32(ctx, "raster.background", w, h, bg);
        let bg = d.create_bind_group(&wgpu::BindGroupDescriptor {
            label: Some("raster.background"),
            layout: &p.layout,
            entries: &[wgpu::BindGroupEntry {
                binding: 2,
                resource: wgpu::BindingResource::TextureView(&view),
            }],
        });
        (p, bg)
    });
    let mesh = match (&s.texture, s.tris.is_empty()) {
        (Some(t), false) => {
            let p = pipe(
                d,
                "raster.mesh",
                &mesh_module,
                mesh_raster::MESH,
                &[uniform_entry(0), storage_entry(1), texture_entry(2)],
                wgpu::PrimitiveTopology::TriangleList,
                Some(wgpu::Face::Back),
                true,
                less,
                n,
            );
            let view = texture_rgba32(ctx, "raster.texture", t.width, t.height, &t.texels);
            let groups = bind_chunks(
                ctx,
                &p,
                "raster.mesh",
                &uniform,
                &s.tris,
                chunk_bytes,
                &view,
            );
            Some((p, groups))
        }
        _ => None,
    };
    // Only this path uses the strand module: the compute passes have their own.
    let strands = (!s.drawn.is_empty() && !vis).then(|| {
        let segs: Vec<strand_raster::SegRec> =
            s.drawn.par_iter().map(|&at| s.seg_rec(at)).collect();
        let strand_module = module(d, strand_src);
        let p = pipe(
            d,
            "raster.strands",
            &strand_module,
            strand_raster::STRANDS,
            &[uniform_entry(0), storage_entry(1), texture_entry(2)],
            // One instance per segment, its corners A B C D as a strip: triangles ABC and
            // BDC (= CBD), the two the CPU mirror rasterises, with 4 vertices instead of 6.
            wgpu::PrimitiveTopology::TriangleStrip,
            None,
            true,
            less,
            n,
        );
        let photo = texture_rgba32_or_blank(ctx, s.photo.as_ref());
        let groups = bind_chunks(
            ctx,
            &p,
            "raster.strands",
            &uniform,
            &segs,
            chunk_bytes,
            &photo,
        );
        (p, groups)
    });

    let mut encoder = d.create_command_encoder(&wgpu::CommandEncoderDescriptor {
        label: Some("raster"),
    });
    let mut queries = crate::gpu::timer::PassQueries::new(ctx, if vis { 6 } else { 1 });
    {
        let mut pass = encoder.begin_render_pass(&wgpu::RenderPassDescriptor {
            label: Some("raster"),
            color_attachments: &[Some(wgpu::RenderPassColorAttachment {
                view: &color_view,
                depth_slice: None,
                resolve_target: resolve_view.as_ref(),
                ops: wgpu::Operations {
                    load: wgpu::LoadOp::Clear(wgpu::Color::TRANSPARENT),
                    store: if msaa && !vis {
                        wgpu::StoreOp::Discard
                    } else {
                        wgpu::StoreOp::Store
                    },
                },
            })],
            depth_stencil_attachment: Some(wgpu::RenderPassDepthStencilAttachment {
                view: &depth_view,
                depth_ops: Some(wgpu::Operations {
                    load: wgpu::LoadOp::Clear(1.0),
                    store: if vis {
                        wgpu::StoreOp::Store
                    } else {
                        wgpu::StoreOp::Discard
                    },
                }),
                stencil_ops: None,
            }),
            timestamp_writes: queries.as_mut().map(|q| q.render("raster")),
            occlusion_query_set: None,
            multiview_mask: None,
        });
        if let Some((p, bg)) = &background {
            pass.set_pipeline(&p.pipeline);
            pass.set_bind_group(0, bg, &[]);
            pass.draw(0..3, 0..1);
        }
        // Mesh before strands, chunks in input order: the draw order the CPU mirrors (a
        // triangle list of 3 vertices per triangle; a 4-vertex strip per segment instance).
        if let Some((p, groups)) = &mesh {
            pass.set_pipeline(&p.pipeline);
            for (bg, count) in groups {
                pass.set_bind_group(0, bg, &[]);
                pass.draw(0..3 * count, 0..1);
            }
        }
        if let Some((p, groups)) = &strands {
            pass.set_pipeline(&p.pipeline);
            for (bg, count) in groups {
                pass.set_bind_group(0, bg, &[]);
                pass.draw(0..4, 0..*count);
            }
        }
    }
    // The strands as compute passes, after the background and mesh.
    let vis_out = vis_src.map(|src| {
        vis::encode(
            ctx,
            strand_stage,
            || module(d, src),
            s,
            mesh.is_some(),
            &mut encoder,
            queries.as_mut(),
            &uniform,
            chunk_bytes,
            &color_view,
            &depth_view,
        )
    });
    // The compute resolve's rows are not padded.
    let bytes_per_row = if vis { w * 8 } else { bytes_per_row };
    let readback_bytes = bytes_per_row as u64 * h as u64;
    // From the pool: the copy below fills it whole before it is read.
    let mut readback = ctx.buffer(
        "raster.readback",
        readback_bytes,
        wgpu::BufferUsages::MAP_READ | wgpu::BufferUsages::COPY_DST,
    );
    if let Some(v) = &vis_out {
        encoder.copy_buffer_to_buffer(&v.out, 0, &readback, 0, readback_bytes);
    } else {
        encoder.copy_texture_to_buffer(
            wgpu::TexelCopyTextureInfo {
                texture: resolve.as_ref().unwrap_or(&color),
                mip_level: 0,
                origin: wgpu::Origin3d::ZERO,
                aspect: wgpu::TextureAspect::All,
            },
            wgpu::TexelCopyBufferInfo {
                buffer: &readback,
                layout: wgpu::TexelCopyBufferLayout {
                    offset: 0,
                    bytes_per_row: Some(bytes_per_row),
                    rows_per_image: Some(h),
                },
            },
            wgpu::Extent3d {
                width: w,
                height: h,
                depth_or_array_layers: 1,
            },
        );
    }
    if let Some(q) = &mut queries {
        q.resolve(ctx, &mut encoder);
    }
    ctx.queue.submit([encoder.finish()]);
    readback.slice(..).map_async(wgpu::MapMode::Read, |_| {});
    if let Some(q) = &queries {
        q.map();
    }
    d.poll(wgpu::PollType::wait_indefinitely())
        .map_err(|e| Error::Gpu(format!("device poll failed: {e}")))?;
    if let Some(e) = pollster::block_on(oom.pop()) {
        return Err(Error::Gpu(format!("raster: {e}")));
    }
    if let Some(e) = pollster::block_on(validation.pop()) {
        return Err(Error::Gpu(format!("raster: {e}")));
    }
    ctx.check_errors()?;
    if let Some(q) = queries {
        q.finish(ctx)?;
    }
    let view = readback
        .slice(..)
        .get_mapped_range()
        .map_err(|e| Error::Gpu(format!("cannot map the read-back buffer: {e}")))?;
    let mut img = vec![[0.0f32; 4]; w as usize * h as usize];
    img.par_chunks_mut(w as usize)
        .enumerate()
        .for_each(|(y, row)| {
            let start = y * bytes_per_row as usize;
            let src: &[u8] = &view[start..start + w as usize * 8];
            for (x, px) in row.iter_mut().enumerate() {
                *px = std::array::from_fn(|c| {
                    let o = x * 8 + c * 2;
                    f16_bits_to_f32(u16::from_le_bytes([src[o], src[o + 1]]))
                });
            }
        });
    drop(view);
    readback.unmap();
    Ok(img)
}
