//! The truth planes, each pixel written once.
//!
//! At 1024² a plane is 4 MiB and the all-channel truth has eight of them. Filled with
//! their miss values first (one thread) and then overwritten where a ray hits, they
//! cost more than a third of the pass; here each band of rows is filled by the thread
//! that traces it, just before it does, into memory that was never initialised.

use super::{TruthChannel, TruthChannels, TruthImage};
use rayon::prelude::*;
use std::mem::MaybeUninit;

/// What one pixel-centre ray hits.
pub(super) struct TruthPixel {
    pub mask: u32,
    pub depth: f32,
    pub normal: [f32; 3],
    pub body: [f32; 3],
}

/// Rows `row0..row0 + rows` of every plane asked for, holding their misses until written.
pub(super) struct Band<'a> {
    pub row0: u32,
    pub rows: u32,
    width: usize,
    mask: &'a mut [u32],
    depth: Option<&'a mut [f32]>,
    normal: Option<[&'a mut [f32]; 3]>,
    body: Option<[&'a mut [f32]; 3]>,
}

impl Band<'_> {
    /// Record `p` at (`row`, `col`), `row` counted from the image's top.
    pub fn put(&mut self, row: u32, col: u32, p: &TruthPixel) {
        let i = (row - self.row0) as usize * self.width + col as usize;
        self.mask[i] = p.mask;
        if let Some(d) = self.depth.as_deref_mut() {
            d[i] = p.depth;
        }
        for (plane, v) in [(&mut self.normal, p.normal), (&mut self.body, p.body)] {
            if let Some(pl) = plane {
                for a in 0..3 {
                    pl[a][i] = v[a];
                }
            }
        }
    }
}

/// A `width` × `height` truth of `channels`: `trace` runs on bands of `band_rows` rows in
/// parallel, each band's pixels set to misses first by its own thread (mask 0, depth +∞,
/// NaN vectors).
pub(super) fn fill(
    width: u32,
    height: u32,
    channels: TruthChannels,
    band_rows: u32,
    trace: impl Fn(&mut Band) + Sync,
) -> TruthImage {
    let n = width as usize * height as usize;
    let room = |c| if channels.contains(c) { n } else { 0 };
    let mut mask: Vec<u32> = Vec::with_capacity(n);
    let mut depth: Vec<f32> = Vec::with_capacity(room(TruthChannel::Depth));
    let mut normal: [Vec<f32>; 3] = std::array::from_fn(|_| Vec::with_capacity(room(TruthChannel::Normal)));
    let mut body: [Vec<f32>; 3] = std::array::from_fn(|_| Vec::with_capacity(room(TruthChannel::BodyXyz)));
    let w = width as usize;
    let chunk = w * band_rows.max(1) as usize;
    if n > 0 {
        let mut depth_bands = bands(&mut depth, n, chunk);
        let mut normal_bands = normal.each_mut().map(|p| bands(p, n, chunk));
        let mut body_bands = body.each_mut().map(|p| bands(p, n, chunk));
        let raw: Vec<_> = bands(&mut mask, n, chunk)
            .enumerate()
            .map(|(k, m)| RawBand {
                row0: k as u32 * band_rows.max(1),
                mask: m,
                depth: depth_bands.next(),
                normal: three(&mut normal_bands),
                body: three(&mut body_bands),
            })
            .collect();
        raw.into_par_iter().for_each(|b| trace(&mut b.init(w)));
    }
    // SAFETY: `RawBand::init` wrote every element of the first `n` of each plane asked
    // for (`n` > 0: `bands` cut them all into bands); the others have no capacity and stay
    // empty.
    unsafe {
        for p in std::iter::once(&mut depth).chain(&mut normal).chain(&mut body) {
            if p.capacity() >= n && n > 0 {
                p.set_len(n);
            }
        }
        mask.set_len(n);
    }
    TruthImage { width, height, channels, mask, materials: None, depth, normal, body_xyz: body }
}

type Uninit<'a, T> = &'a mut [MaybeUninit<T>];

/// A band's parts of the planes before its thread writes them.
struct RawBand<'a> {
    row0: u32,
    mask: Uninit<'a, u32>,
    depth: Option<Uninit<'a, f32>>,
    normal: Option<[Uninit<'a, f32>; 3]>,
    body: Option<[Uninit<'a, f32>; 3]>,
}

impl<'a> RawBand<'a> {
    /// The band with every pixel a miss.
    fn init(self, width: usize) -> Band<'a> {
        let rows = (self.mask.len() / width.max(1)) as u32;
        Band {
            row0: self.row0,
            rows,
            width,
            mask: init(self.mask, 0),
            depth: self.depth.map(|d| init(d, f32::INFINITY)),
            normal: self.normal.map(|p| p.map(|c| init(c, f32::NAN))),
            body: self.body.map(|p| p.map(|c| init(c, f32::NAN))),
        }
    }
}

/// The first `n` elements of `v`'s spare capacity in chunks of `chunk`; none when `v`
/// has no room for `n` (a channel not asked for).
fn bands<T>(v: &mut Vec<T>, n: usize, chunk: usize) -> std::vec::IntoIter<Uninit<'_, T>> {
    let spare = v.spare_capacity_mut();
    let parts: Vec<_> = if spare.len() < n { Vec::new() } else { spare[..n].chunks_mut(chunk).collect() };
    parts.into_iter()
}

/// `c` filled with `miss`, as initialised values.
fn init<T: Copy>(c: Uninit<'_, T>, miss: T) -> &mut [T] {
    c.fill(MaybeUninit::new(miss));
    // SAFETY: every element was just written; `MaybeUninit<T>` has `T`'s layout.
    unsafe { &mut *(c as *mut [MaybeUninit<T>] as *mut [T]) }
}

/// The next band of three planes.
fn three<'a>(p: &mut [std::vec::IntoIter<Uninit<'a, f32>>; 3]) -> Option<[Uninit<'a, f32>; 3]> {
    let [x, y, z] = p.each_mut().map(|it| it.next());
    Some([x?, y?, z?])
}
