//! How a scene file names a material: `BsdfSpec` (serde) → validated [`Bsdf`].
//!
//! ```toml
//! bsdf = { model = "lambert", rho = 0.522 }
//! bsdf = { model = "improved_blinn_phong", preset = "gold_polyimide" }
//! bsdf = { model = "improved_blinn_phong", preset = "gold_polyimide", normalized = true }
//! bsdf = { model = "blinn_phong", rho_d = 0.3, rho_s = 20.0, alpha = 200.0 }
//! bsdf = { model = "cook_torrance", rho_d = 0.3, roughness = 0.1, f0 = 0.9 }
//! bsdf = { model = "ggx_conductor", roughness = 0.3, metal = "Au" }    # or n, k; or f0
//! bsdf = { model = "ggx_plastic", roughness = 0.5, rho = 0.5, ior = 1.5 }
//! bsdf = { model = "ggx_plastic", roughness = 0.5, rho = 0.5, coupling = "mitsuba" }
//! bsdf = { model = "ggx_metallic_roughness", base_color = 0.8, metallic = 1.0, roughness = 0.4 }
//! ```
//! Explicit fields override the preset's; without a preset every field is required.

use super::{
    BlinnPhong, Bsdf, BsdfError, ConductorFresnel, CookTorrance, Coupling, Ggx, ImprovedBlinnPhong, Lambert, Metal,
};
use serde::Deserialize;

/// Named parameter sets.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum Preset {
    /// Gold polyimide MLI: the paper's fit for `improved_blinn_phong`; our fits of the other
    /// lobe models to that curve (docs/brdf.md); for `lambert`, its diffuse albedo 0.3717.
    GoldPolyimide,
    /// The paper's matt white paint, Lambert ρ = 0.522 (`lambert` only).
    WhitePaint,
}

/// A material's BRDF as written in a scene file (tagged by `model`).
#[derive(Clone, Debug, PartialEq, Deserialize)]
#[serde(tag = "model", rename_all = "snake_case", deny_unknown_fields)]
pub enum BsdfSpec {
    /// `f_r = ρ/π`.
    Lambert {
        #[serde(default)]
        preset: Option<Preset>,
        #[serde(default)]
        rho: Option<f32>,
    },
    /// Eq. (4): `ρd/π + ρs (n·h)^α / (n·l)`.
    BlinnPhong {
        #[serde(default)]
        preset: Option<Preset>,
        #[serde(default)]
        rho_d: Option<f32>,
        #[serde(default)]
        rho_s: Option<f32>,
        #[serde(default)]
        alpha: Option<f32>,
        /// Scale ρs so the directional albedo is ≤ 1 at every view angle.
        #[serde(default)]
        normalized: bool,
    },
    /// Eq. (5): `ρd/π + ρs (n·h)^α / (n·l)^a · exp(−b (1 − n·h)^(1/π))`.
    ImprovedBlinnPhong {
        #[serde(default)]
        preset: Option<Preset>,
        #[serde(default)]
        rho_d: Option<f32>,
        #[serde(default)]
        rho_s: Option<f32>,
        #[serde(default)]
        alpha: Option<f32>,
        #[serde(default)]
        a: Option<f32>,
        #[serde(default)]
        b: Option<f32>,
        /// Scale ρs so the directional albedo is ≤ 1 at every view angle.
        #[serde(default)]
        normalized: bool,
    },
    /// Beckmann / Smith / Schlick microfacet lobe plus `ρd/π`.
    CookTorrance {
        #[serde(default)]
        preset: Option<Preset>,
        #[serde(default)]
        rho_d: Option<f32>,
        /// Beckmann RMS slope m.
        #[serde(default)]
        roughness: Option<f32>,
        #[serde(default)]
        f0: Option<f32>,
        /// Specular scale (default 1).
        #[serde(default)]
        k_s: Option<f32>,
        /// Scale k_s so the directional albedo is ≤ 1 at every view angle.
        #[serde(default)]
        normalized: bool,
    },
    /// GGX conductor: `D G F / (4 cosθo cosθi)`, F from `metal`, or `n` and `k`, or `f0`.
    GgxConductor {
        /// α = roughness² (glTF / Disney).
        #[serde(default)]
        roughness: Option<f32>,
        /// A named conductor: `Au`, `Al`, `Ag`, `Cu`.
        #[serde(default)]
        metal: Option<Metal>,
        #[serde(default)]
        n: Option<f32>,
        #[serde(default)]
        k: Option<f32>,
        /// Schlick's F0 instead of a complex index.
        #[serde(default)]
        f0: Option<f32>,
    },
    /// GGX dielectric coating of index `ior` (default 1.5) over Lambert `rho`.
    GgxPlastic {
        #[serde(default)]
        roughness: Option<f32>,
        #[serde(default)]
        rho: Option<f32>,
        #[serde(default)]
        ior: Option<f32>,
        /// How the base is coupled to the coating: `energy` (default) or `mitsuba`.
        #[serde(default)]
        coupling: Coupling,
    },
    /// glTF 2.0's metallic-roughness material at one band.
    GgxMetallicRoughness {
        #[serde(default)]
        base_color: Option<f32>,
        #[serde(default)]
        metallic: Option<f32>,
        #[serde(default)]
        roughness: Option<f32>,
    },
}

/// A conductor's Fresnel term from exactly one of `metal`, `n` + `k`, `f0`.
fn conductor_fresnel(
    metal: Option<Metal>,
    n: Option<f32>,
    k: Option<f32>,
    f0: Option<f32>,
) -> Result<ConductorFresnel, BsdfError> {
    const M: &str = "ggx_conductor";
    let conflict = |field| BsdfError::Invalid {
        model: M,
        field,
        value: f32::NAN,
        reason: "conflicts with another Fresnel choice: give one of `metal`, `n` and `k`, `f0`",
    };
    match (metal, n, k, f0) {
        (Some(m), None, None, None) => {
            let [n, k] = m.nk();
            Ok(ConductorFresnel::Complex { n, k })
        }
        (None, Some(n), Some(k), None) => Ok(ConductorFresnel::Complex { n, k }),
        (None, None, None, Some(f0)) => Ok(ConductorFresnel::Schlick { f0 }),
        (None, Some(_), None, None) => Err(BsdfError::Missing { model: M, field: "k" }),
        (None, None, Some(_), None) => Err(BsdfError::Missing { model: M, field: "n" }),
        (None, None, None, None) => Err(BsdfError::Missing { model: M, field: "metal" }),
        (Some(_), ..) => Err(conflict("metal")),
        _ => Err(conflict("f0")),
    }
}

fn pick(
    model: &'static str,
    field: &'static str,
    explicit: Option<f32>,
    preset: Option<f32>,
) -> Result<f32, BsdfError> {
    explicit.or(preset).ok_or(BsdfError::Missing { model, field })
}

/// Upper ends of the lobe parameters (the constructors check the lower ends and
/// finiteness): a Blinn–Phong `rho_s` or `alpha` of 1e6 is already a mirror far beyond any
/// fitted surface (the gold-polyimide fits have ~280 and ~4000), and larger values only
/// overflow f32 in the lobe's normalisation.
const MAX_RHO_S: f32 = 1.0e6;
const MAX_ALPHA: f32 = 1.0e6;
/// Improved Blinn–Phong's Fresnel-like `b` and Cook–Torrance's `k_s` scale the lobe.
const MAX_SCALE: f32 = 1.0e3;

fn at_most(model: &'static str, field: &'static str, v: f32, max: f32, reason: &'static str) -> Result<f32, BsdfError> {
    if v <= max { Ok(v) } else { Err(BsdfError::Invalid { model, field, value: v, reason }) }
}

fn wrong_preset(model: &'static str) -> BsdfError {
    BsdfError::Invalid { model, field: "preset", value: f32::NAN, reason: "is not defined for this model" }
}

impl BsdfSpec {
    /// Validate and build.
    ///
    /// # Errors
    /// [`BsdfError`] naming the model and the offending or missing field.
    pub fn build(&self) -> Result<Bsdf, BsdfError> {
        use Preset::*;
        match *self {
            BsdfSpec::Lambert { preset, rho } => {
                let p = match preset {
                    None => None,
                    Some(GoldPolyimide) => Some(ImprovedBlinnPhong::GOLD_POLYIMIDE[0]),
                    Some(WhitePaint) => Some(0.522),
                };
                Ok(Bsdf::Lambert(Lambert::new(pick("lambert", "rho", rho, p)?)?))
            }
            BsdfSpec::BlinnPhong { preset, rho_d, rho_s, alpha, normalized } => {
                const M: &str = "blinn_phong";
                let p = match preset {
                    None => None,
                    Some(GoldPolyimide) => Some(BlinnPhong::GOLD_POLYIMIDE_FIT),
                    Some(WhitePaint) => return Err(wrong_preset(M)),
                };
                let b = BlinnPhong::new(
                    pick(M, "rho_d", rho_d, p.map(|p| p[0]))?,
                    at_most(M, "rho_s", pick(M, "rho_s", rho_s, p.map(|p| p[1]))?, MAX_RHO_S, "must be ≤ 1e6")?,
                    at_most(M, "alpha", pick(M, "alpha", alpha, p.map(|p| p[2]))?, MAX_ALPHA, "must be ≤ 1e6")?,
                )?;
                Ok(Bsdf::BlinnPhong(if normalized { b.normalized() } else { b }))
            }
            BsdfSpec::ImprovedBlinnPhong { preset, rho_d, rho_s, alpha, a, b, normalized } => {
                const M: &str = "improved_blinn_phong";
                let p = match preset {
                    None => None,
                    Some(GoldPolyimide) => Some(ImprovedBlinnPhong::GOLD_POLYIMIDE),
                    Some(WhitePaint) => return Err(wrong_preset(M)),
                };
                let m = ImprovedBlinnPhong::new(
                    pick(M, "rho_d", rho_d, p.map(|p| p[0]))?,
                    at_most(M, "rho_s", pick(M, "rho_s", rho_s, p.map(|p| p[1]))?, MAX_RHO_S, "must be ≤ 1e6")?,
                    at_most(M, "alpha", pick(M, "alpha", alpha, p.map(|p| p[2]))?, MAX_ALPHA, "must be ≤ 1e6")?,
                    pick(M, "a", a, p.map(|p| p[3]))?,
                    at_most(M, "b", pick(M, "b", b, p.map(|p| p[4]))?, MAX_SCALE, "must be ≤ 1000")?,
                )?;
                Ok(Bsdf::ImprovedBlinnPhong(if normalized { m.normalized() } else { m }))
            }
            BsdfSpec::CookTorrance { preset, rho_d, roughness, f0, k_s, normalized } => {
                const M: &str = "cook_torrance";
                let p = match preset {
                    None => None,
                    Some(GoldPolyimide) => Some(CookTorrance::GOLD_POLYIMIDE_FIT),
                    Some(WhitePaint) => return Err(wrong_preset(M)),
                };
                let c = CookTorrance::new(
                    pick(M, "rho_d", rho_d, p.map(|p| p[0]))?,
                    pick(M, "roughness", roughness, p.map(|p| p[1]))?,
                    pick(M, "f0", f0, p.map(|p| p[2]))?,
                    at_most(M, "k_s", k_s.or(p.map(|p| p[3])).unwrap_or(1.0), MAX_SCALE, "must be ≤ 1000")?,
                )?;
                Ok(Bsdf::CookTorrance(if normalized { c.normalized() } else { c }))
            }
            BsdfSpec::GgxConductor { roughness, metal, n, k, f0 } => {
                let r = pick("ggx_conductor", "roughness", roughness, None)?;
                Ok(Bsdf::Ggx(Ggx::conductor(r, conductor_fresnel(metal, n, k, f0)?)?))
            }
            BsdfSpec::GgxPlastic { roughness, rho, ior, coupling } => {
                const M: &str = "ggx_plastic";
                let g = Ggx::plastic_coupled(
                    pick(M, "roughness", roughness, None)?,
                    pick(M, "rho", rho, None)?,
                    ior.unwrap_or(super::GLTF_DIELECTRIC_IOR),
                    coupling,
                )?;
                Ok(Bsdf::Ggx(g))
            }
            BsdfSpec::GgxMetallicRoughness { base_color, metallic, roughness } => {
                const M: &str = "ggx_metallic_roughness";
                let g = Ggx::metallic_roughness(
                    pick(M, "base_color", base_color, None)?,
                    pick(M, "metallic", metallic, None)?,
                    pick(M, "roughness", roughness, None)?,
                )?;
                Ok(Bsdf::Ggx(g))
            }
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn parse(s: &str) -> Result<BsdfSpec, toml::de::Error> {
        #[derive(Deserialize)]
        struct W {
            bsdf: BsdfSpec,
        }
        toml::from_str::<W>(&format!("bsdf = {s}")).map(|w| w.bsdf)
    }

    #[test]
    fn parses_the_documented_forms() {
        let l = parse(r#"{ model = "lambert", rho = 0.522 }"#).unwrap().build().unwrap();
        assert_eq!(l.is_lambertian(), Some(0.522));
        let p = parse(r#"{ model = "improved_blinn_phong", preset = "gold_polyimide" }"#).unwrap().build().unwrap();
        assert_eq!(p, Bsdf::ImprovedBlinnPhong(ImprovedBlinnPhong::gold_polyimide()));
        let n = parse(r#"{ model = "improved_blinn_phong", preset = "gold_polyimide", normalized = true }"#)
            .unwrap()
            .build()
            .unwrap();
        let Bsdf::ImprovedBlinnPhong(n) = n else { panic!() };
        assert!(n.normalization < 0.6 && n.normalization > 0.2, "{}", n.normalization);
        // An explicit field overrides the preset.
        let o = parse(r#"{ model = "improved_blinn_phong", preset = "gold_polyimide", a = 1.0 }"#)
            .unwrap()
            .build()
            .unwrap();
        let Bsdf::ImprovedBlinnPhong(o) = o else { panic!() };
        assert_eq!((o.lobe.a, o.lobe.alpha), (1.0, 3865.7));
        for s in [
            r#"{ model = "blinn_phong", preset = "gold_polyimide" }"#,
            r#"{ model = "cook_torrance", preset = "gold_polyimide" }"#,
            r#"{ model = "cook_torrance", rho_d = 0.1, roughness = 0.2, f0 = 0.5 }"#,
            r#"{ model = "lambert", preset = "white_paint" }"#,
            r#"{ model = "ggx_conductor", roughness = 0.3, metal = "Au" }"#,
            r#"{ model = "ggx_conductor", roughness = 0.3, n = 1.2, k = 7.3 }"#,
            r#"{ model = "ggx_conductor", roughness = 0.3, f0 = 0.9 }"#,
            r#"{ model = "ggx_plastic", roughness = 0.5, rho = 0.5, ior = 1.5 }"#,
            r#"{ model = "ggx_plastic", roughness = 0.5, rho = 0.5 }"#,
            r#"{ model = "ggx_metallic_roughness", base_color = 0.8, metallic = 0.5, roughness = 0.4 }"#,
        ] {
            parse(s).unwrap().build().unwrap();
        }
    }

    #[test]
    fn lobe_parameters_have_upper_ends() {
        for (text, field) in [
            ("{ model = \"blinn_phong\", rho_d = 0.1, rho_s = 1e7, alpha = 10 }", "rho_s"),
            ("{ model = \"blinn_phong\", rho_d = 0.1, rho_s = 1, alpha = 3e38 }", "alpha"),
            ("{ model = \"improved_blinn_phong\", rho_d = 0.1, rho_s = 1, alpha = 10, a = 0.5, b = 1e4 }", "b"),
            ("{ model = \"cook_torrance\", rho_d = 0.1, roughness = 0.1, f0 = 0.5, k_s = 1e30 }", "k_s"),
            ("{ model = \"blinn_phong\", rho_d = 0.1, rho_s = 1e39, alpha = 10 }", "rho_s"),
            ("{ model = \"lambert\", rho = nan }", "rho"),
        ] {
            // An f32 overflow may already fail to parse; either way the value is refused.
            let e = match parse(text) {
                Ok(spec) => spec.build().unwrap_err().to_string(),
                Err(e) => e.to_string(),
            };
            assert!(e.contains(field), "{text}: {e}");
        }
    }

    #[test]
    fn errors_name_the_field() {
        let e = parse(r#"{ model = "lambert", rho = 1.5 }"#).unwrap().build().unwrap_err();
        assert!(e.to_string().contains("`rho`"), "{e}");
        let e = parse(r#"{ model = "improved_blinn_phong", preset = "gold_polyimide", a = 1.2 }"#)
            .unwrap()
            .build()
            .unwrap_err();
        assert!(e.to_string().contains("`a`"), "{e}");
        let e = parse(r#"{ model = "blinn_phong", rho_d = 0.3, rho_s = 2.0 }"#).unwrap().build().unwrap_err();
        assert_eq!(e, BsdfError::Missing { model: "blinn_phong", field: "alpha" });
        let e = parse(r#"{ model = "cook_torrance", rho_d = 0.3, roughness = 0.0, f0 = 0.5 }"#)
            .unwrap()
            .build()
            .unwrap_err();
        assert!(e.to_string().contains("`roughness`"), "{e}");
        let e = parse(r#"{ model = "blinn_phong", preset = "white_paint" }"#).unwrap().build().unwrap_err();
        assert!(e.to_string().contains("`preset`"), "{e}");
        for (text, field) in [
            (r#"{ model = "ggx_conductor", roughness = 0.3 }"#, "`metal`"),
            (r#"{ model = "ggx_conductor", roughness = 0.3, n = 1.0 }"#, "`k`"),
            (r#"{ model = "ggx_conductor", roughness = 0.3, metal = "Au", f0 = 0.5 }"#, "`metal`"),
            (r#"{ model = "ggx_conductor", roughness = 0.3, n = 1.0, k = 2.0, f0 = 0.5 }"#, "`f0`"),
            (r#"{ model = "ggx_conductor", roughness = 0.001, metal = "Al" }"#, "`roughness`"),
            (r#"{ model = "ggx_conductor", roughness = 0.3, n = -1.0, k = 2.0 }"#, "`n`"),
            (r#"{ model = "ggx_plastic", roughness = 0.3, rho = 0.5, ior = 0.5 }"#, "`ior`"),
            (r#"{ model = "ggx_plastic", roughness = 0.3 }"#, "`rho`"),
            (
                r#"{ model = "ggx_metallic_roughness", base_color = 0.5, metallic = 2.0, roughness = 0.5 }"#,
                "`metallic`",
            ),
        ] {
            let e = parse(text).unwrap().build().unwrap_err();
            assert!(e.to_string().contains(field), "{text}: {e}");
        }
        let e = parse(r#"{ model = "ggx_conductor", roughness = 0.3, metal = "Pt" }"#).unwrap_err();
        assert!(e.to_string().contains("Pt"), "{e}");
        // Unknown fields and models are rejected by serde, naming them.
        let e = parse(r#"{ model = "lambert", rho = 0.5, roh = 1 }"#).unwrap_err();
        assert!(e.to_string().contains("roh"), "{e}");
        let e = parse(r#"{ model = "phong", rho = 0.5 }"#).unwrap_err();
        assert!(e.to_string().contains("phong"), "{e}");
    }
}
