//! Buffers and textures kept from one call to the next that asks for the same ones
//! ([`GpuContext::buffer`], [`GpuContext::texture`]).
//!
//! Why: on a CPU driver (lavapipe) a new buffer or texture is fresh memory that the kernel
//! faults in and zeroes page by page, and wgpu zeroes it once more before its first use (a
//! buffer mapped at creation on the calling thread, any other on the driver's queue
//! thread). A 1024² strand render makes about 250 MB of them (the segments, the visibility
//! samples, the multisampled targets): 0.2 s of its 0.7 s went to that, on one thread,
//! before and between the shaders. A frame of a video, a batch of portraits or a bench round
//! asks for the same sizes again, and gets them back without either cost.
//!
//! A kept resource holds whatever its last user left in it: only what is fully written
//! before it is read may be pooled (each caller says why its uses are).

use super::GpuContext;

/// Bytes the pool keeps at most; past it, the resources given back longest ago are freed.
/// (Two 2048² strand renders' worth.)
pub const POOL_BYTES: u64 = 1 << 30;

/// What a pooled resource was made as; a request takes only an exact match.
#[derive(Clone, Copy, PartialEq, Eq, Debug)]
enum Key {
    Buffer {
        label: &'static str,
        size: u64,
        usage: wgpu::BufferUsages,
    },
    Texture {
        label: &'static str,
        size: wgpu::Extent3d,
        samples: u32,
        format: wgpu::TextureFormat,
        usage: wgpu::TextureUsages,
    },
}

/// A resource the pool holds.
#[derive(Clone, Debug)]
pub enum Res {
    Buffer(wgpu::Buffer),
    Texture(wgpu::Texture),
}

/// The resources given back, oldest first, and their bytes (`R`: a [`Res`] but in tests).
pub(super) struct Pool<R = Res> {
    kept: Vec<(Key, R, u64)>,
    bytes: u64,
}

impl<R> Default for Pool<R> {
    fn default() -> Self {
        Pool {
            kept: Vec::new(),
            bytes: 0,
        }
    }
}

impl<R> Pool<R> {
    fn take(&mut self, key: Key) -> Option<R> {
        // The newest match: the one the previous call of the same shape gave back.
        let at = self.kept.iter().rposition(|(k, _, _)| *k == key)?;
        let (_, res, bytes) = self.kept.remove(at);
        self.bytes -= bytes;
        Some(res)
    }

    fn give(&mut self, key: Key, res: R, bytes: u64) {
        self.kept.push((key, res, bytes));
        self.bytes += bytes;
        while self.bytes > POOL_BYTES {
            let (_, _, b) = self.kept.remove(0);
            self.bytes -= b;
        }
    }

    /// Bytes kept now.
    pub(super) fn bytes(&self) -> u64 {
        self.bytes
    }

    pub(super) fn clear(&mut self) {
        self.kept.clear();
        self.bytes = 0;
    }
}

/// A buffer or texture from the pool, given back to it when dropped. (Dropped while the
/// GPU still uses it is fine: the queue runs in order, so its next user's work runs after.)
pub struct Pooled<'a, T: Clone + Into<Res>> {
    ctx: &'a GpuContext,
    key: Key,
    bytes: u64,
    res: T,
    /// False for a mappable buffer until [`Pooled::unmap`]: one a caller left mapped (or
    /// its map pending, returning early on an error) is freed, not given back.
    give_back: bool,
}

impl Pooled<'_, wgpu::Buffer> {
    /// Unmaps the buffer, which may then go back to the pool.
    pub fn unmap(&mut self) {
        self.res.unmap();
        self.give_back = true;
    }
}

impl From<wgpu::Buffer> for Res {
    fn from(b: wgpu::Buffer) -> Res {
        Res::Buffer(b)
    }
}

impl From<wgpu::Texture> for Res {
    fn from(t: wgpu::Texture) -> Res {
        Res::Texture(t)
    }
}

impl<T: Clone + Into<Res>> std::ops::Deref for Pooled<'_, T> {
    type Target = T;
    fn deref(&self) -> &T {
        &self.res
    }
}

impl<T: Clone + Into<Res>> Drop for Pooled<'_, T> {
    fn drop(&mut self) {
        if !self.give_back {
            return;
        }
        let res = self.res.clone().into();
        self.ctx
            .pool
            .lock()
            .unwrap()
            .give(self.key, res, self.bytes);
    }
}

impl GpuContext {
    /// A buffer of `size` bytes with `usage`, not mapped: one a previous call gave back
    /// (its contents whatever that call left), else a new one (zeroed, as wgpu makes them).
    pub fn buffer(
        &self,
        label: &'static str,
        size: u64,
        usage: wgpu::BufferUsages,
    ) -> Pooled<'_, wgpu::Buffer> {
        let key = Key::Buffer { label, size, usage };
        let kept = self.pool.lock().unwrap().take(key);
        let res = match kept {
            Some(Res::Buffer(b)) => b,
            _ => self.device.create_buffer(&wgpu::BufferDescriptor {
                label: Some(label),
                size,
                usage,
                mapped_at_creation: false,
            }),
        };
        let mappable =
            usage.intersects(wgpu::BufferUsages::MAP_READ | wgpu::BufferUsages::MAP_WRITE);
        self.hold(key, size, res, !mappable)
    }

    /// `res`, made as `key` (`bytes` of it), to be given back to the pool when dropped
    /// (when `give_back`, or once [`Pooled::unmap`] says so).
    fn hold<T: Clone + Into<Res>>(
        &self,
        key: Key,
        bytes: u64,
        res: T,
        give_back: bool,
    ) -> Pooled<'_, T> {
        Pooled {
            ctx: self,
            key,
            bytes,
            res,
            give_back,
        }
    }

    /// A 2D texture of one mip level: one a previous call gave back (its texels whatever
    /// that call left), else a new one.
    pub fn texture(
        &self,
        label: &'static str,
        size: wgpu::Extent3d,
        samples: u32,
        format: wgpu::TextureFormat,
        usage: wgpu::TextureUsages,
    ) -> Pooled<'_, wgpu::Texture> {
        let key = Key::Texture {
            label,
            size,
            samples,
            format,
            usage,
        };
        let kept = self.pool.lock().unwrap().take(key);
        let res = match kept {
            Some(Res::Texture(t)) => t,
            _ => self.device.create_texture(&wgpu::TextureDescriptor {
                label: Some(label),
                size,
                mip_level_count: 1,
                sample_count: samples,
                dimension: wgpu::TextureDimension::D2,
                format,
                usage,
                view_formats: &[],
            }),
        };
        let texel = format.block_copy_size(None).unwrap_or(16) as u64;
        let bytes = size.width as u64
            * size.height as u64
            * size.depth_or_array_layers as u64
            * samples as u64
            * texel;
        self.hold(key, bytes, res, true)
    }

    /// Bytes of buffers and textures the pool keeps now.
    pub fn pooled_bytes(&self) -> u64 {
        self.pool.lock().unwrap().bytes()
    }

    /// Frees every buffer and texture the pool keeps (e.g. between jobs of very different
    /// sizes).
    pub fn release_pool(&self) {
        self.pool.lock().unwrap().clear();
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn key(size: u64) -> Key {
        Key::Buffer {
            label: "t",
            size,
            usage: wgpu::BufferUsages::STORAGE,
        }
    }

    /// The bookkeeping (numbers stand in for the resources): exact matches only, the newest
    /// first, and past the cap the oldest are freed.
    #[test]
    fn pool_takes_exact_matches_and_keeps_to_its_cap() {
        let mut p = Pool::<u32>::default();
        assert_eq!(p.take(key(8)), None);
        p.give(key(8), 1, 8);
        p.give(key(16), 2, 16);
        p.give(key(8), 3, 8);
        assert_eq!(p.bytes(), 32);
        assert_eq!(p.take(key(4)), None);
        let storage_8 = Key::Buffer {
            label: "other",
            size: 8,
            usage: wgpu::BufferUsages::STORAGE,
        };
        assert_eq!(p.take(storage_8), None, "another label is another key");
        assert_eq!(p.take(key(8)), Some(3));
        assert_eq!(p.take(key(8)), Some(1));
        assert_eq!(p.take(key(8)), None);
        assert_eq!(p.bytes(), 16);
        // Up to the cap everything stays; past it the oldest go first, until the rest fit.
        let half = POOL_BYTES / 2;
        p.give(key(half), 4, half);
        p.give(key(half - 16), 5, half - 16);
        assert_eq!(p.bytes(), POOL_BYTES, "at the cap, nothing freed");
        p.give(key(2), 6, 2);
        assert_eq!(p.bytes(), POOL_BYTES - 14, "the oldest (16 B) freed");
        assert_eq!(p.take(key(16)), None);
        p.give(key(32), 7, 32);
        assert_eq!(p.take(key(half)), None, "then the oldest big one");
        assert_eq!(p.take(key(half - 16)), Some(5));
        assert_eq!(p.bytes(), 34);
        p.clear();
        assert_eq!(
            (p.bytes(), p.take(key(2)), p.take(key(32))),
            (0, None, None)
        );
    }
}
