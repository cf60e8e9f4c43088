//! A `[materials.NAME]` table: the BRDF (`model = …` and its fields, `BsdfSpec`) and the
//! radiance the surface emits (`emission`, W·sr⁻¹·m⁻² in the band, default 0).
//!
//! ```toml
//! [materials.beacon]
//! model = "lambert"
//! rho = 0.1
//! emission = 250.0     # W·sr⁻¹·m⁻², from both sides
//! ```

use crate::render::bsdf::BsdfSpec;
use serde::Deserialize;
use serde::de::Error;

/// Largest `emission` taken, W·sr⁻¹·m⁻²: far beyond any surface on a spacecraft (the
/// sun's own disc is 2e7 in the band) and finite in f32.
pub const MAX_EMISSION: f64 = 1.0e9;

#[derive(Clone, Debug, PartialEq)]
pub struct MaterialEntry {
    pub bsdf: BsdfSpec,
    /// Emitted radiance, W·sr⁻¹·m⁻² in the band.
    pub emission: f64,
}

impl<'de> Deserialize<'de> for MaterialEntry {
    fn deserialize<D: serde::Deserializer<'de>>(d: D) -> Result<Self, D::Error> {
        // `emission` is taken out before the rest goes to the BRDF's tagged enum, which
        // refuses fields it does not know.
        let mut table = toml::Table::deserialize(d)?;
        let emission = match table.remove("emission") {
            None => 0.0,
            Some(toml::Value::Float(v)) => v,
            Some(toml::Value::Integer(v)) => v as f64,
            Some(other) => return Err(D::Error::custom(format!("emission: expected a number, got `{other}`"))),
        };
        if !(emission.is_finite() && (0.0..=MAX_EMISSION).contains(&emission)) {
            return Err(D::Error::custom(format!("emission: {emission} must be in [0, {MAX_EMISSION:e}] W·sr⁻¹·m⁻²")));
        }
        let bsdf = BsdfSpec::deserialize(toml::Value::Table(table)).map_err(D::Error::custom)?;
        Ok(MaterialEntry { bsdf, emission })
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn emission_is_read_beside_the_brdf_and_checked() {
        let e: MaterialEntry = toml::from_str("model = \"lambert\"\nrho = 0.5\nemission = 12").unwrap();
        assert_eq!(e.emission, 12.0);
        assert_eq!(e.bsdf.build().unwrap().is_lambertian(), Some(0.5));
        let e: MaterialEntry = toml::from_str("model = \"lambert\"\nrho = 0.5").unwrap();
        assert_eq!(e.emission, 0.0);
        for bad in ["emission = -1.0", "emission = \"x\"", "emission = inf"] {
            let err = toml::from_str::<MaterialEntry>(&format!("model = \"lambert\"\nrho = 0.5\n{bad}")).unwrap_err();
            assert!(err.to_string().contains("emission:"), "{bad}: {err}");
        }
        // The BRDF's own checks still name unknown fields.
        let err = toml::from_str::<MaterialEntry>("model = \"lambert\"\nrho = 0.5\nrh = 1").unwrap_err();
        assert!(err.to_string().contains("rh"), "{err}");
    }
}
