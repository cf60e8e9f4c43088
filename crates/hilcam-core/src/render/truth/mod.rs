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

mod pass;
mod planes;

pub use pass::{render_truth, render_truth_into, render_truth_reference, render_truth_with};
pub use planes::TruthPlanes;

use crate::render::target::Material;

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
