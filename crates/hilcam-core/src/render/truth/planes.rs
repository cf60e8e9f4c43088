//! The truth planes, kept from frame to frame.
//!
//! At 1024² a plane is 4 MiB and the all-channel truth has eight of them. Allocated and
//! filled with their miss values for every frame, they cost a sixth of the pass; kept in
//! a [`TruthPlanes`], only the rows the last truth wrote hits into are set back to misses
//! (by the thread that then traces them), as the frame's image is cleared. Every pixel
//! outside those rows already holds its miss, so the bytes do not depend on what was
//! computed before.

use super::{TruthChannel, TruthChannels, TruthImage};
use rayon::prelude::*;
use std::mem::MaybeUninit;
use std::ops::Range;

/// What one pixel-centre ray hits.
pub(super) struct TruthPixel {
    pub mask: u32,
    pub depth: f32,
    pub normal: [f32; 3],
    pub body: [f32; 3],
}

/// A truth's planes, kept by whoever asks for truth frame after frame
/// (`render_truth_into`, `FramePipeline::truth_into`): after the first frame of a size
/// and channel set nothing is allocated and only the rows hit last time are cleared.
#[derive(Default)]
pub struct TruthPlanes {
    image: Option<TruthImage>,
    /// Rows of `image` that may hold hits; every other pixel of each plane of full length
    /// holds its miss.
    hit_rows: Range<u32>,
}

impl TruthPlanes {
    /// The last truth computed into these planes.
    pub fn image(&self) -> Option<&TruthImage> {
        self.image.as_ref()
    }

    /// The last truth, leaving no planes (the next truth allocates them again).
    pub fn take(&mut self) -> Option<TruthImage> {
        self.hit_rows = 0..0;
        self.image.take()
    }
}

/// Rows `row0..row0 + rows` of every plane asked for, holding misses until written.
pub(super) struct Band<'a> {
    pub row0: u32,
    pub rows: u32,
    width: usize,
    mask: &'a mut [u32],
    depth: Option<&'a mut [f32]>,
    normal: Option<[&'a mut [f32]; 3]>,
    body: Option<[&'a mut [f32]; 3]>,
    /// Rows (image rows) `put` wrote a hit into.
    hit: Range<u32>,
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
        self.hit = match self.hit.is_empty() {
            true => row..row + 1,
            false => self.hit.start.min(row)..self.hit.end.max(row + 1),
        };
    }
}

/// A `width` × `height` truth of `channels` in `planes`: `trace` runs on bands of
/// `band_rows` rows in parallel, each band's pixels that may hold an earlier truth's hits
/// set to misses first by its own thread (mask 0, depth +∞, NaN vectors): the rows hit
/// last time in a plane kept, every row in a plane new to these planes.
pub(super) fn fill(
    planes: &mut TruthPlanes,
    width: u32,
    height: u32,
    channels: TruthChannels,
    band_rows: u32,
    trace: impl Fn(&mut Band) + Sync,
) -> &mut TruthImage {
    let n = width as usize * height as usize;
    let kept = planes.image.take().filter(|t| (t.width, t.height) == (width, height));
    let stale = if kept.is_some() { planes.hit_rows.clone() } else { 0..0 };
    let mut t = kept.unwrap_or_else(|| TruthImage {
        width,
        height,
        channels,
        mask: Vec::new(),
        materials: None,
        depth: Vec::new(),
        normal: Default::default(),
        body_xyz: Default::default(),
    });
    t.channels = channels;
    let w = width as usize;
    let rows = band_rows.max(1);
    let chunk = w * rows as usize;
    let ask = |c| channels.contains(c).then_some(n);
    let mut hit = 0..0;
    {
        let mut depth = parts(&mut t.depth, ask(TruthChannel::Depth), chunk);
        let mut normal = t.normal.each_mut().map(|p| parts(p, ask(TruthChannel::Normal), chunk));
        let mut body = t.body_xyz.each_mut().map(|p| parts(p, ask(TruthChannel::BodyXyz), chunk));
        let raw: Vec<_> = parts(&mut t.mask, Some(n), chunk)
            .enumerate()
            .map(|(k, mask)| RawBand {
                row0: k as u32 * rows,
                mask,
                depth: depth.next(),
                normal: three(&mut normal),
                body: three(&mut body),
            })
            .collect();
        if n > 0 {
            hit = raw
                .into_par_iter()
                .map(|b| {
                    let mut b = b.init(w, &stale);
                    trace(&mut b);
                    b.hit
                })
                .reduce(|| 0..0, union);
        }
    }
    // SAFETY: a plane asked for is either `n` long already or has room for `n` elements
    // that `RawBand::init` has all written (`n` > 0: `parts` cut them into the bands).
    unsafe {
        for (p, c) in [(&mut t.depth, TruthChannel::Depth)]
            .into_iter()
            .chain(t.normal.iter_mut().map(|p| (p, TruthChannel::Normal)))
            .chain(t.body_xyz.iter_mut().map(|p| (p, TruthChannel::BodyXyz)))
        {
            if channels.contains(c) && n > 0 {
                p.set_len(n);
            }
        }
        if n > 0 {
            t.mask.set_len(n);
        }
    }
    planes.hit_rows = hit;
    planes.image.insert(t)
}

/// The smallest range holding both.
fn union(a: Range<u32>, b: Range<u32>) -> Range<u32> {
    match (a.is_empty(), b.is_empty()) {
        (true, _) => b,
        (_, true) => a,
        _ => a.start.min(b.start)..a.end.max(b.end),
    }
}

/// A band's part of one plane before its thread clears it.
enum Part<'a, T> {
    /// Kept from the last truth: misses outside the rows it hit.
    Kept(&'a mut [T]),
    /// Never initialised.
    Fresh(&'a mut [MaybeUninit<T>]),
}

impl<'a, T: Copy> Part<'a, T> {
    /// The part with every pixel a miss, given that a kept one may hold hits only in
    /// `stale` (element ranges of the part).
    fn init(self, stale: Range<usize>, miss: T) -> &'a mut [T] {
        match self {
            Part::Kept(p) => {
                let (a, b) = (stale.start.min(p.len()), stale.end.min(p.len()));
                if a < b {
                    p[a..b].fill(miss);
                }
                p
            }
            Part::Fresh(c) => {
                c.fill(MaybeUninit::new(miss));
                // SAFETY: every element was just written; `MaybeUninit<T>` has `T`'s layout.
                unsafe { &mut *(c as *mut [MaybeUninit<T>] as *mut [T]) }
            }
        }
    }
}

/// A plane's bands of `chunk` elements: none when the plane is not asked for (`n` None;
/// it is emptied, keeping its memory), its kept elements when it is `n` long, else room for
/// `n` elements never initialised.
fn parts<T>(v: &mut Vec<T>, n: Option<usize>, chunk: usize) -> std::vec::IntoIter<Part<'_, T>> {
    let chunk = chunk.max(1);
    let parts: Vec<_> = match n {
        None => {
            v.clear();
            Vec::new()
        }
        Some(n) if v.len() == n => v.chunks_mut(chunk).map(Part::Kept).collect(),
        Some(n) => {
            v.clear();
            v.reserve_exact(n);
            v.spare_capacity_mut()[..n].chunks_mut(chunk).map(Part::Fresh).collect()
        }
    };
    parts.into_iter()
}

/// The next band of three planes.
fn three<'a>(p: &mut [std::vec::IntoIter<Part<'a, f32>>; 3]) -> Option<[Part<'a, f32>; 3]> {
    let [x, y, z] = p.each_mut().map(|it| it.next());
    Some([x?, y?, z?])
}

/// A band's parts of the planes before its thread clears them.
struct RawBand<'a> {
    row0: u32,
    mask: Part<'a, u32>,
    depth: Option<Part<'a, f32>>,
    normal: Option<[Part<'a, f32>; 3]>,
    body: Option<[Part<'a, f32>; 3]>,
}

impl<'a> RawBand<'a> {
    /// The band with every pixel a miss, given that kept planes hold hits only in the
    /// image rows `stale`.
    fn init(self, width: usize, stale: &Range<u32>) -> Band<'a> {
        let len = match &self.mask {
            Part::Kept(p) => p.len(),
            Part::Fresh(p) => p.len(),
        };
        let rows = (len / width.max(1)) as u32;
        let (a, b) = (stale.start.max(self.row0), stale.end.min(self.row0 + rows));
        let span = if a < b { (a - self.row0) as usize * width..(b - self.row0) as usize * width } else { 0..0 };
        Band {
            row0: self.row0,
            rows,
            width,
            mask: self.mask.init(span.clone(), 0),
            depth: self.depth.map(|d| d.init(span.clone(), f32::INFINITY)),
            normal: self.normal.map(|p| p.map(|c| c.init(span.clone(), f32::NAN))),
            body: self.body.map(|p| p.map(|c| c.init(span.clone(), f32::NAN))),
            hit: 0..0,
        }
    }
}
