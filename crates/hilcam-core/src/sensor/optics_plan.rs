//! The image-space optics (τ, cos⁴, PSF) planned once per sensor and window, for the
//! fused pass to run row by row with the arithmetic of [`super::Sensor::optics`] and
//! [`super::Sensor::optics_variance`] (the same bits).

use super::config::{OpticsConfig, PsfConfig};
use super::psf::Kernel;
use super::psf_band::{SeparablePsf, Span};
use crate::render::camera::{CameraModel, Window};

/// The per-pixel factor `τ·cos⁴θ` of one window, by rows and columns.
#[derive(Clone, Debug)]
pub struct Scale {
    tau: f64,
    /// `(f², x² per column, y² per row)` in pixels, when cos⁴ is on: `cos²θ = f²/(f² + x² + y²)`.
    cos4: Option<(f64, Vec<f64>, Vec<f64>)>,
}

/// How the PSF runs in the fused pass.
#[derive(Clone, Debug)]
pub enum PsfPlan {
    None,
    /// A separable kernel, row by row.
    Separable(Box<SeparablePsf>),
    /// A 2D kernel (Airy): over the whole image first.
    Whole,
}

impl Scale {
    /// `None` when the optics scale nothing (τ = 1, no cos⁴): the radiance passes unchanged.
    pub fn new(o: &OpticsConfig, camera: &CameraModel, window: &Window) -> Option<Scale> {
        let tau = o.transmittance.unwrap_or(1.0);
        if tau == 1.0 && !o.cos4 {
            return None;
        }
        // As `optics::cos4` forms them, at the window's place on the array.
        let cos4 = o.cos4.then(|| {
            let f = camera.focal_px();
            let sq = |v: f64| v * v;
            let x = (0..window.width)
                .map(|c| sq((f64::from(c + window.x) + 0.5) - camera.width as f64 / 2.0 - camera.principal_point_px[0]))
                .collect();
            let y = (0..window.height)
                .map(|r| {
                    sq((f64::from(r + window.y) + 0.5) - camera.height as f64 / 2.0 - camera.principal_point_px[1])
                })
                .collect();
            (f * f, x, y)
        });
        Some(Scale { tau, cos4 })
    }

    /// `dst[c] = src[c]·τ cos⁴θ` over `span` of window row `row` (`squared`: times the
    /// factor twice, for a variance).
    #[inline]
    pub fn row(&self, row: usize, src: &[f32], (a, b): Span, squared: bool, dst: &mut [f32]) {
        let (d, s) = (&mut dst[a..b], &src[a..b]);
        match &self.cos4 {
            None => {
                let f = self.tau;
                for (d, s) in d.iter_mut().zip(s) {
                    *d = if squared { (*s as f64 * f * f) as f32 } else { (*s as f64 * f) as f32 };
                }
            }
            Some((ff, x2, y2)) => {
                let y2 = y2[row];
                for ((d, s), x2) in d.iter_mut().zip(s).zip(&x2[a..b]) {
                    let c2 = ff / (ff + x2 + y2);
                    let f = self.tau * (c2 * c2);
                    *d = if squared { (*s as f64 * f * f) as f32 } else { (*s as f64 * f) as f32 };
                }
            }
        }
    }
}

impl PsfPlan {
    pub fn new(psf: &Option<PsfConfig>, kernels: &[Kernel], window: &Window) -> PsfPlan {
        match (psf, kernels) {
            (None, _) => PsfPlan::None,
            (Some(PsfConfig::Gaussian { .. }), [h, v]) => {
                PsfPlan::Separable(Box::new(SeparablePsf::new(h, v, window.width as usize, window.height as usize)))
            }
            _ => PsfPlan::Whole,
        }
    }
}
