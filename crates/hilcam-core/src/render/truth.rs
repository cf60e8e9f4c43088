//! Ground truth beside a frame: per pixel, what the line of sight through the pixel
//! centre hits — range (m), material mask, surface normal (camera frame) and the hit
//! point in the target body frame — plus the target's footprint on the image (centroid
//! and bounding box of the mask).
//!
//! Truth is a function of (scene, view) only: one ray per pixel through its centre, in a
//! pass of its own, the exposure start's pose (the pose the frame is tagged with; a
//! moving view's blur is not averaged in). So it is the same for any spp, sampler, seed or
//! thread count by construction, and the frame loop is untouched: off costs nothing.
//! The channels are the pixel-centre sample, not a pixel average: an average depth or
//! normal across an edge is a surface that does not exist.
//!
//! The tracer finds the triangle (f32); the hit point is then recomputed in f64 as the
//! exact crossing of the pixel-centre line with that triangle's plane, so range and body
//! coordinates carry no f32 ray rounding (only the stored f32 of the channel).

use crate::render::camera::View;
use crate::render::cull::coverage::Coverage;
use crate::render::target::{Material, Target};
use glam::DVec3;
use rayon::prelude::*;

/// One truth channel, by its command-line / config name.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum TruthChannel {
    /// Range from the camera centre to the hit along the ray, metres (+inf on a miss).
    Depth,
    /// The hit's material number, 0 on a miss: 1 + the material's index with the
    /// scene's materials sorted by name (byte order, as `[materials.NAME]` keys sort);
    /// [`TruthImage::materials`] names them.
    Mask,
    /// Unit face normal in the camera frame, turned to face the camera (NaN on a miss).
    Normal,
    /// Hit point in the target body frame, metres (NaN on a miss).
    BodyXyz,
}

impl TruthChannel {
    pub const ALL: [TruthChannel; 4] =
        [TruthChannel::Depth, TruthChannel::Mask, TruthChannel::Normal, TruthChannel::BodyXyz];

    pub fn name(self) -> &'static str {
        match self {
            TruthChannel::Depth => "depth",
            TruthChannel::Mask => "mask",
            TruthChannel::Normal => "normal",
            TruthChannel::BodyXyz => "body_xyz",
        }
    }

    fn bit(self) -> u8 {
        1 << self as u8
    }
}

/// A set of truth channels (empty: no truth is computed).
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct TruthChannels(u8);

impl TruthChannels {
    pub const NONE: TruthChannels = TruthChannels(0);

    pub fn is_empty(self) -> bool {
        self.0 == 0
    }

    pub fn contains(self, c: TruthChannel) -> bool {
        self.0 & c.bit() != 0
    }

    pub fn with(self, c: TruthChannel) -> TruthChannels {
        TruthChannels(self.0 | c.bit())
    }

    /// The channels in canonical order.
    pub fn iter(self) -> impl Iterator<Item = TruthChannel> {
        TruthChannel::ALL.into_iter().filter(move |&c| self.contains(c))
    }

    /// Parse names such as `depth,mask,normal,body_xyz` (any order, repeats allowed); an
    /// unknown name is refused with the allowed list.
    pub fn parse(list: &str) -> Result<TruthChannels, String> {
        Self::from_names(list.split(',').map(str::trim).filter(|s| !s.is_empty()))
    }

    /// The set of the channels named `names`.
    pub fn from_names<'a>(names: impl IntoIterator<Item = &'a str>) -> Result<TruthChannels, String> {
        let mut set = TruthChannels::NONE;
        for n in names {
            let c = TruthChannel::ALL.into_iter().find(|c| c.name() == n).ok_or_else(|| {
                let allowed: Vec<_> = TruthChannel::ALL.iter().map(|c| c.name()).collect();
                format!("unknown truth channel `{n}` (allowed: {})", allowed.join(", "))
            })?;
            set = set.with(c);
        }
        Ok(set)
    }
}

impl std::fmt::Display for TruthChannels {
    /// Comma-separated names in canonical order (empty for none).
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        let names: Vec<_> = self.iter().map(TruthChannel::name).collect();
        f.write_str(&names.join(","))
    }
}

/// The truth channels of one frame, row-major like the image. Channels not asked for are
/// empty vectors; the mask is always filled (the footprint is computed from it).
#[derive(Clone, Debug, PartialEq)]
pub struct TruthImage {
    pub width: u32,
    pub height: u32,
    pub channels: TruthChannels,
    /// Material index + 1 of the hit, 0 where the ray misses.
    pub mask: Vec<u32>,
    /// The mask's id → material-name table, [`materials_table`] of the scene (filled by
    /// [`render_truth`]; the stream and GigE send it with the mask).
    pub materials: Option<std::sync::Arc<str>>,
    pub depth: Vec<f32>,
    /// x, y, z planes.
    pub normal: [Vec<f32>; 3],
    /// x, y, z planes.
    pub body_xyz: [Vec<f32>; 3],
}

/// The mask table of `materials` (the scene's, in mask order): `1=name;2=name;…`, mask
/// value = material index + 1; names ASCII-escaped as Rust's `escape_default` writes them
/// (`é` as `\u{e9}`), so the table is ASCII (EXR text is Latin-1).
pub fn materials_table(materials: &[Material]) -> String {
    let pairs: Vec<_> =
        materials.iter().enumerate().map(|(i, m)| format!("{}={}", i + 1, m.name.escape_default())).collect();
    pairs.join(";")
}

/// Where the target lies on the image: the pixels whose centre ray hits it.
#[derive(Clone, Copy, Debug, PartialEq, serde::Serialize, serde::Deserialize)]
pub struct Footprint {
    /// Mean of the hit pixels' centres, continuous pixel coordinates (x, y): pixel
    /// (col, row) has its centre at (col + 0.5, row + 0.5).
    pub centroid_px: [f64; 2],
    /// [col0, row0, col1, row1], half-open: the hit pixels' columns are col0..col1 and
    /// rows row0..row1 (in continuous coordinates, the box's edges).
    pub bbox_px: [u32; 4],
    /// Number of hit pixels.
    pub pixels: u64,
}

impl TruthImage {
    /// The target's footprint, `None` when no pixel centre sees it.
    pub fn footprint(&self) -> Option<Footprint> {
        let w = self.width as usize;
        let (mut sx, mut sy, mut n) = (0.0f64, 0.0f64, 0u64);
        let mut bbox = [u32::MAX, u32::MAX, 0, 0];
        for (i, _) in self.mask.iter().enumerate().filter(|(_, m)| **m != 0) {
            let (col, row) = ((i % w) as u32, (i / w) as u32);
            sx += f64::from(col) + 0.5;
            sy += f64::from(row) + 0.5;
            n += 1;
            bbox = [bbox[0].min(col), bbox[1].min(row), bbox[2].max(col + 1), bbox[3].max(row + 1)];
        }
        (n > 0).then(|| Footprint { centroid_px: [sx / n as f64, sy / n as f64], bbox_px: bbox, pixels: n })
    }
}

/// What the pixel-centre ray of one pixel hits.
#[derive(Clone, Copy)]
struct TruthPixel {
    mask: u32,
    depth: f32,
    normal: [f32; 3],
    body: [f32; 3],
}

const MISS: TruthPixel = TruthPixel { mask: 0, depth: f32::INFINITY, normal: [f32::NAN; 3], body: [f32::NAN; 3] };

/// Pixels computed together (in parallel) before they are scattered into the channel
/// planes: bounds the temporary buffer at any image size.
const BAND_PIXELS: usize = 64 * 1024;

/// The truth of `target` through `view` (its exposure-start instant): one ray through each
/// pixel centre that may see a triangle (inside `View::pixel_rect` and marked by the
/// BVH leaves' projected boxes, `cull::coverage`, both conservative; every other pixel is
/// a miss without a ray). Rayon over pixels; every pixel is a pure function of
/// (target, view), so any thread count gives the same values.
pub fn render_truth(target: &Target, view: &View, channels: TruthChannels) -> TruthImage {
    let (width, height) = view.size();
    let n = width as usize * height as usize;
    let plane = |c, miss| if channels.contains(c) { vec![miss; n] } else { Vec::new() };
    let planes3 = |c| [plane(c, f32::NAN), plane(c, f32::NAN), plane(c, f32::NAN)];
    let mut out = TruthImage {
        width,
        height,
        channels,
        mask: vec![0; n],
        materials: Some(materials_table(&target.materials).into()),
        depth: plane(TruthChannel::Depth, MISS.depth),
        normal: planes3(TruthChannel::Normal),
        body_xyz: planes3(TruthChannel::BodyXyz),
    };
    let Some(rect) = (if target.accel.is_empty() { None } else { view.pixel_rect() }) else { return out };
    let (w, rw) = (width as usize, (rect.col1 - rect.col0) as usize);
    let band_rows = (BAND_PIXELS / rw.max(1)).max(1);
    let mut coverage = Coverage::default();
    let covered = coverage.from_leaf_boxes(target, view, rect);
    let may_hit = |row, col| !covered || coverage.may_hit(row, col);
    let mut band = Vec::new();
    for row0 in (rect.row0 as usize..rect.row1 as usize).step_by(band_rows) {
        let rows = row0..(row0 + band_rows).min(rect.row1 as usize);
        (0..rows.len() * rw)
            .into_par_iter()
            .map(|k| {
                let (col, row) = (rect.col0 + (k % rw) as u32, (row0 + k / rw) as u32);
                if may_hit(row, col) { pixel(target, view, col, row) } else { MISS }
            })
            .collect_into_vec(&mut band);
        for (k, p) in band.iter().enumerate().filter(|(_, p)| p.mask != 0) {
            let i = (row0 + k / rw) * w + rect.col0 as usize + k % rw;
            out.mask[i] = p.mask;
            if let Some(d) = out.depth.get_mut(i) {
                *d = p.depth;
            }
            for a in 0..3 {
                if let Some(v) = out.normal[a].get_mut(i) {
                    *v = p.normal[a];
                }
                if let Some(v) = out.body_xyz[a].get_mut(i) {
                    *v = p.body[a];
                }
            }
        }
    }
    out
}

/// Truth of pixel (`col`, `row`): the triangle the f32 tracer hits along the pixel-centre
/// ray, the hit point recomputed in f64 on that triangle's plane.
fn pixel(target: &Target, view: &View, col: u32, row: u32) -> TruthPixel {
    let (x, y) = (f64::from(col) + 0.5, f64::from(row) + 0.5);
    let Some(ray) = view.primary_ray(x, y) else { return MISS };
    let Some(hit) = target.accel.intersect(&ray) else { return MISS };
    // The line in f64: camera centre `o`, direction `d` (render frame).
    let d_cam = view.camera_dir(x, y);
    let d = view.cam_to_render * d_cam;
    let o = view.origin;
    let [a, _, _] = target.mesh.triangle(hit.tri as usize);
    let n = hit.normal.as_dvec3();
    let denom = n.dot(d);
    let s = n.dot(a.as_dvec3() - o) / denom;
    // A line grazing the plane: keep the tracer's own f32 point.
    let p = if s.is_finite() && s > 0.0 { o + d * s } else { (ray.origin + ray.dir * hit.t).as_dvec3() };
    let depth = (p - o).length();
    let mut n_cam = view.cam_to_render.transpose() * n;
    if n_cam.dot(d_cam) > 0.0 {
        n_cam = -n_cam;
    }
    let body: DVec3 = p + target.frame_origin_body;
    TruthPixel {
        mask: hit.material + 1,
        depth: depth as f32,
        normal: n_cam.as_vec3().to_array(),
        body: body.as_vec3().to_array(),
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn channel_lists_parse_in_any_order_and_unknown_names_list_the_allowed_ones() {
        let c = TruthChannels::parse("body_xyz, depth,depth").unwrap();
        assert_eq!(c.to_string(), "depth,body_xyz");
        assert!(TruthChannels::parse("").unwrap().is_empty());
        let e = TruthChannels::parse("depth,range").unwrap_err();
        assert_eq!(e, "unknown truth channel `range` (allowed: depth, mask, normal, body_xyz)");
    }

    #[test]
    fn footprint_is_the_mean_centre_and_half_open_box_of_the_mask() {
        let mut t = TruthImage {
            width: 4,
            height: 3,
            channels: TruthChannels::NONE,
            mask: vec![0; 12],
            materials: None,
            depth: vec![],
            normal: Default::default(),
            body_xyz: Default::default(),
        };
        assert_eq!(t.footprint(), None);
        t.mask[4 + 1] = 1; // (col 1, row 1)
        t.mask[2 * 4 + 3] = 2; // (col 3, row 2)
        let f = t.footprint().unwrap();
        assert_eq!(f.centroid_px, [2.5, 2.0]);
        assert_eq!(f.bbox_px, [1, 1, 4, 3]);
        assert_eq!(f.pixels, 2);
    }
}
