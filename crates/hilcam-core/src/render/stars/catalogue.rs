//! The star catalogue file: CSV with a header naming at least `ra_deg`, `dec_deg` and
//! `vmag` (J2000 right ascension and declination in degrees, Johnson V magnitude), and
//! optionally `hr` (any other column, e.g. `name`, is ignored). `#` lines are comments.
//! Errors name the file, line and column.

use super::{Star, StarField};
use glam::DQuat;
use std::path::{Path, PathBuf};

/// Spectral flux density of a V = 0 star at the top of the atmosphere, W·m⁻²·nm⁻¹:
/// 3.63 × 10⁻⁹ erg·s⁻¹·cm⁻²·Å⁻¹ (Bessell, Castelli & Plez 1998, A&A 333, 231, Table A2,
/// Johnson V, λ_eff 545 nm).
pub const V_ZERO_FLUX_W_M2_NM: f64 = 3.63e-11;

/// Band irradiance of a V = 0 star over `[min_um, max_um]`, W/m²: the V-band flux density
/// taken as flat across the band (the sensor model assumes a flat spectrum too).
pub fn band_zero_point_w_m2(min_um: f64, max_um: f64) -> f64 {
    V_ZERO_FLUX_W_M2_NM * (max_um - min_um) * 1e3
}

#[derive(Debug, thiserror::Error)]
pub enum StarCatalogueError {
    #[error("{path}: {source}")]
    Io { path: PathBuf, source: std::io::Error },
    #[error("{path}:{line}:{column}: {message}")]
    Parse { path: PathBuf, line: usize, column: usize, message: String },
}

/// Which stars to keep and how bright V = 0 is.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Selection {
    /// Keep stars with `min_vmag ≤ V ≤ max_vmag`.
    pub min_vmag: f64,
    pub max_vmag: f64,
    pub zero_point_w_m2: f64,
    pub default_camera_to_inertial: DQuat,
}

impl StarField {
    /// Read a catalogue file and keep the stars `sel` selects.
    pub fn load(path: &Path, sel: &Selection) -> Result<StarField, StarCatalogueError> {
        let text =
            std::fs::read_to_string(path).map_err(|source| StarCatalogueError::Io { path: path.into(), source })?;
        Self::parse(&text, path, sel)
    }

    /// Parse catalogue text (`path` names it in errors).
    pub fn parse(text: &str, path: &Path, sel: &Selection) -> Result<StarField, StarCatalogueError> {
        let err = |line: usize, column: usize, message: String| StarCatalogueError::Parse {
            path: path.into(),
            line,
            column,
            message,
        };
        let mut rows = text
            .lines()
            .enumerate()
            .map(|(i, l)| (i + 1, l.trim()))
            .filter(|(_, l)| !l.is_empty() && !l.starts_with('#'));
        let Some((hline, header)) = rows.next() else { return Err(err(1, 0, "no header line".into())) };
        let names: Vec<&str> = header.split(',').map(str::trim).collect();
        let find = |n: &str| names.iter().position(|h| *h == n);
        let need = |n: &str| find(n).ok_or_else(|| err(hline, 0, format!("missing column `{n}` (header: {header})")));
        let (ra, dec, vmag, hr) = (need("ra_deg")?, need("dec_deg")?, need("vmag")?, find("hr"));
        let mut field = StarField {
            stars: Vec::new(),
            zero_point_w_m2: sel.zero_point_w_m2,
            default_camera_to_inertial: sel.default_camera_to_inertial,
        };
        for (k, (line, row)) in rows.enumerate() {
            let fields: Vec<&str> = row.split(',').map(str::trim).collect();
            let num = |c: usize, what: &str, lo: f64, hi: f64| -> Result<f64, StarCatalogueError> {
                let f = fields.get(c).copied().unwrap_or("");
                f.parse::<f64>()
                    .ok()
                    .filter(|v| (lo..=hi).contains(v))
                    .ok_or_else(|| err(line, c + 1, format!("`{what}`: `{f}` is not a number in [{lo}, {hi}]")))
            };
            let v = num(vmag, "vmag", -30.0, 30.0)?;
            let (a, d) = (num(ra, "ra_deg", 0.0, 360.0)?, num(dec, "dec_deg", -90.0, 90.0)?);
            let number = match hr {
                Some(c) => num(c, "hr", 0.0, f64::from(u32::MAX))? as u32,
                None => k as u32 + 1,
            };
            if (sel.min_vmag..=sel.max_vmag).contains(&v) {
                let irradiance_w_m2 = field.irradiance_of(v);
                field.stars.push(Star { hr: number, dir: StarField::direction(a, d), vmag: v, irradiance_w_m2 });
            }
        }
        Ok(field)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn sel() -> Selection {
        Selection {
            min_vmag: -30.0,
            max_vmag: 6.0,
            zero_point_w_m2: band_zero_point_w_m2(0.45, 0.75),
            default_camera_to_inertial: DQuat::IDENTITY,
        }
    }

    #[test]
    fn zero_point_gives_the_sun_near_the_solar_band_irradiance() {
        // The sun (V = −26.74, Bessell 1998 Table A2's solar colours) through the same
        // zero point over 0.45–0.75 µm: 541 W/m², 9 % under the paper's 593.1 W/m² — the
        // size of the error of a flat spectrum across a 300 nm band.
        let e = band_zero_point_w_m2(0.45, 0.75) * 10f64.powf(0.4 * 26.74);
        assert!((e - 541.3).abs() < 1.0, "{e}");
    }

    #[test]
    fn rows_are_read_filtered_and_errors_name_line_and_column() {
        let text = "# c\nhr,ra_deg,dec_deg,vmag,name\n2061,88.79292,7.40694,0.50,58Alp Ori\n1,0,0,6.7,x\n";
        let f = StarField::parse(text, Path::new("s.csv"), &sel()).unwrap();
        assert_eq!(f.stars.len(), 1);
        assert_eq!(f.stars[0].hr, 2061);
        assert!((f.stars[0].irradiance_w_m2 - f.zero_point_w_m2 * 10f64.powf(-0.2)).abs() < 1e-20);
        let d = f.stars[0].dir;
        assert!((d.z - 7.40694f64.to_radians().sin()).abs() < 1e-15 && (d.length() - 1.0).abs() < 1e-15);
        let e = StarField::parse("ra_deg,dec_deg,vmag\n1,95,3\n", Path::new("s.csv"), &sel()).unwrap_err();
        assert_eq!(e.to_string(), "s.csv:2:2: `dec_deg`: `95` is not a number in [-90, 90]");
        let e = StarField::parse("ra_deg,vmag\n", Path::new("s.csv"), &sel()).unwrap_err();
        assert!(e.to_string().starts_with("s.csv:1:0: missing column `dec_deg`"), "{e}");
    }
}
