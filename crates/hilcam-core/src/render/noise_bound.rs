//! The camera's own temporal noise at each pixel, in the renderer's units.
//!
//! A frame rendered with `quality = "sensor"` gives each pixel samples until the Monte
//! Carlo standard deviation of its mean, converted to electrons, is below `k` times the
//! camera's temporal noise there: √(signal + dark + read²) e⁻ with shot noise on. The
//! sensor model builds a [`NoiseBound`] for the frame's integration time
//! (`Sensor::noise_bound`); the renderer only reads it (render never depends on sensor).
//!
//! The renderer's pixel is the one before the PSF. A PSF averages neighbouring pixels'
//! independent Monte Carlo errors: where they have about the same variance, the frame's
//! pixel keeps Σw² of it (0.14 for the nav camera's Gaussian, `psf_factor`), so the
//! renderer may leave 1/Σw² times more variance than the frame's pixel is allowed. Where
//! a pixel's variance stands out from its neighbours' (an isolated glint) the PSF spreads
//! it and the frame's pixels there may exceed the bound: the sensor's report, taken on
//! the converted frame, counts them. Photo-response non-uniformity (≤ a few per cent of
//! the gain) is left out.

/// What "as good as the camera" means for one frame (see the module comment).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct NoiseBound {
    /// Monte Carlo standard deviation allowed, as a fraction of the camera's temporal noise.
    pub k: f64,
    /// Photo-electrons per unit radiance (W·sr⁻¹·m⁻²) over the integration time on the
    /// optical axis: transmittance, aperture, pixel area, QE, integration time.
    pub e_per_radiance: f64,
    /// Temporal noise variance that does not grow with the signal, e⁻²: read noise², plus
    /// the mean dark charge when shot noise is on.
    pub floor_e2: f64,
    /// Shot noise on: the camera's variance grows with the signal.
    pub shot: bool,
    /// Natural vignetting (None when the optics have no cos⁴ term).
    pub cos4: Option<Cos4>,
    /// Σw² of the PSF's weights (1 without a PSF): the share of a pixel's Monte Carlo
    /// variance its converted value keeps when its neighbours' is alike.
    pub psf_factor: f64,
}

/// cos⁴θ of a pixel, θ its field angle: the camera's focal length and optical centre in
/// sensor pixels (the same formula as `sensor::optics::cos4`).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Cos4 {
    pub focal_px: f64,
    /// Optical centre, sensor pixels from the array's corner (x right, y down).
    pub centre: [f64; 2],
}

impl Cos4 {
    /// cos⁴θ at the centre of sensor pixel (`row`, `col`).
    #[inline]
    pub fn at(&self, row: u32, col: u32) -> f64 {
        let x = col as f64 + 0.5 - self.centre[0];
        let y = row as f64 + 0.5 - self.centre[1];
        let f2 = self.focal_px * self.focal_px;
        let c2 = f2 / (f2 + x * x + y * y);
        c2 * c2
    }
}

impl NoiseBound {
    /// Photo-electrons per unit radiance at sensor pixel (`row`, `col`).
    #[inline]
    pub fn e_per_radiance_at(&self, row: u32, col: u32) -> f64 {
        self.e_per_radiance * self.cos4.map_or(1.0, |c| c.at(row, col))
    }

    /// The camera's temporal noise variance (e⁻²) at an expected photo-charge of
    /// `signal_e`.
    #[inline]
    pub fn camera_variance_e2(&self, signal_e: f64) -> f64 {
        self.floor_e2 + if self.shot { signal_e.max(0.0) } else { 0.0 }
    }

    /// The largest Monte Carlo variance of a pixel's radiance mean (radiance²) that meets
    /// the bound, for a pixel of mean radiance `radiance` at sensor pixel (`row`, `col`).
    #[inline]
    pub fn allowed_radiance_variance(&self, radiance: f64, row: u32, col: u32) -> f64 {
        let c = self.e_per_radiance_at(row, col);
        if c <= 0.0 {
            return f64::INFINITY;
        }
        self.k * self.k * self.camera_variance_e2(radiance * c) / (c * c * self.psf_factor)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_allowed_variance_is_k_squared_times_the_cameras_in_radiance_units() {
        let b = NoiseBound { k: 0.5, e_per_radiance: 100.0, floor_e2: 25.0, shot: true, cos4: None, psf_factor: 1.0 };
        // 2 W·sr⁻¹·m⁻² → 200 e⁻; camera variance 225 e⁻²; allowed (0.5·15 e⁻)² = 56.25 e⁻²,
        // i.e. 56.25 / 100² radiance².
        assert!((b.allowed_radiance_variance(2.0, 0, 0) - 56.25e-4).abs() < 1e-12);
        let no_shot = NoiseBound { shot: false, ..b };
        assert_eq!(no_shot.camera_variance_e2(1e6), 25.0);
        // A PSF keeping a seventh of the variance allows seven times more before it.
        let psf = NoiseBound { psf_factor: 1.0 / 7.0, ..b };
        assert!((psf.allowed_radiance_variance(2.0, 0, 0) - 7.0 * 56.25e-4).abs() < 1e-12);
    }

    #[test]
    fn vignetting_lowers_the_gain_off_axis() {
        let c = Cos4 { focal_px: 1000.0, centre: [512.0, 512.0] };
        assert!((c.at(511, 511) - 1.0).abs() < 1e-6);
        // 1000 px off axis at f = 1000 px: θ = 45°, cos⁴ = 1/4.
        assert!((c.at(511, 1511) - 0.25).abs() < 1e-3);
    }
}
