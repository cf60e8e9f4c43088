//! An MTL material as its author wrote it → a BRDF, for materials without a
//! `[materials.NAME]` table (docs/scene.md, "MTL materials"). Every key is either used
//! or named in a note with its file and line ("`Ps` ignored: panel.mtl:4").
//!
//! - A colour is reduced to hilcam's one band as the mean of its three values (the
//!   camera's 450–750 nm band spans blue, green and red about equally).
//! - With the PBR extension (`Pr`, `Pm`, `map_Pr` or `map_Pm`): GGX, roughness `Pr` (default 1, α = Pr²),
//!   metallic `Pm` (default 0), base colour `Kd` (default 1): `Pm` 1 is a conductor with
//!   Schlick F0 = `Kd`, `Pm` 0 a rough plastic (index `Ni`, default 1.5) over Lambert
//!   `Kd`, between them glTF's blend. `Ks` and `Ns` are then unused. `map_Pr` and
//!   `map_Pm` give them texel by texel (an image's first channel, linear, times `Pr`,
//!   `Pm`; 1 where absent).
//! - Without it: Lambert `Kd` when `Ks` is absent or black; otherwise a rough plastic over
//!   Lambert `Kd` whose coating reflects F0 = `Ks` at normal incidence (index
//!   `(1 + √F0)/(1 − √F0)`, F0 at most 0.36 = index 4) with the Blinn–Phong exponent `Ns`
//!   mapped to GGX by Walter et al. 2007's `α = √(2/(Ns + 2))` (`Ns` default 0: α = 1).
//!   `Ni` is then MTL's refraction index of transparent materials, unused.
//! - `Ke r g b` (≥ 0, may exceed 1) is emission relative to sunlit white (E/π,
//!   `authored::AuthoredEmission`); `map_Ke` its texture (sRGB, times `Ke`).

use super::authored::{AuthoredBsdf, AuthoredEmission, MIN_ROUGHNESS, metallic_roughness_textured, over_band};
use super::mtl::{MtlKey, MtlMaterial};
use super::texture_file::{ImageSource, TextureRef};
use crate::render::bsdf::{Bsdf, Ggx, Lambert};

/// Largest dielectric F0 a `Ks` maps to: the coating's index is at most 4.
const MAX_DIELECTRIC_F0: f32 = 0.36;

/// `Kd r [g b]` → the band value (g and b default to r, as MTL says).
fn band(m: &MtlMaterial, k: &MtlKey) -> Result<f32, String> {
    let [r, g, b] = rgb(m, k)?;
    unit(m, k, (r + g + b) / 3.0)
}

/// A colour key's `r g b` (g and b default to r).
fn rgb(m: &MtlMaterial, k: &MtlKey) -> Result<[f32; 3], String> {
    let v: Vec<f32> = k.args.iter().map(|a| a.parse::<f32>()).collect::<Result<_, _>>().map_err(|_| {
        format!("{}: {}: `{}` is not `{} r g b` (numbers)", m.at(k.line), k.key, k.args.join(" "), k.key)
    })?;
    match v.as_slice() {
        [r] => Ok([*r; 3]),
        [r, g, b] => Ok([*r, *g, *b]),
        _ => Err(format!("{}: {}: needs 1 or 3 numbers, got {}", m.at(k.line), k.key, v.len())),
    }
}

/// Largest `Ke` component: 1e6 × sunlit white is far beyond any lamp on a spacecraft and
/// keeps the radiance finite in f32.
const MAX_KE: f32 = 1.0e6;

/// `Ke r g b` and `map_Ke`: the material's emission, if it emits.
fn emission(m: &MtlMaterial, notes: &mut Vec<String>) -> Result<Option<AuthoredEmission>, String> {
    let ke = match m.get("Ke") {
        None => None,
        Some(k) => {
            let c = rgb(m, k)?;
            if c.iter().any(|v| !(0.0..=MAX_KE).contains(v)) {
                return Err(format!("{}: Ke: `{}` must be in [0, {MAX_KE:e}]", m.at(k.line), k.args.join(" ")));
            }
            Some(c)
        }
    };
    let texture = m.get("map_Ke").map(|k| map_file(m, k, over_band(ke.unwrap_or([1.0; 3])), notes)).transpose()?;
    if texture.is_some() && ke.is_none() {
        let k = m.get("map_Ke").expect("map_Ke read");
        notes.push(format!("`map_Ke` used with `Ke 1 1 1` (the material gives no `Ke`): {}", m.at(k.line)));
    }
    let c = ke.unwrap_or([1.0; 3]);
    if c == [0.0; 3] {
        if let Some(t) = texture {
            notes.push(format!("`map_Ke` `{}` ignored: `Ke` is black: {}", t.name(), t.at));
        }
        return Ok(None);
    }
    if texture.is_none() && ke.is_none() {
        return Ok(None);
    }
    let relative = (c[0] + c[1] + c[2]) / 3.0;
    Ok(Some(AuthoredEmission { relative, texture }))
}

fn unit(m: &MtlMaterial, k: &MtlKey, v: f32) -> Result<f32, String> {
    if (0.0..=1.0).contains(&v) { Ok(v) } else { Err(format!("{}: {}: {v} must be in [0, 1]", m.at(k.line), k.key)) }
}

fn scalar(m: &MtlMaterial, k: &MtlKey) -> Result<f32, String> {
    match k.args.as_slice() {
        [a] => a
            .parse::<f32>()
            .ok()
            .filter(|v| v.is_finite())
            .ok_or_else(|| format!("{}: {}: `{a}` is not a finite number", m.at(k.line), k.key)),
        _ => Err(format!("{}: {}: needs one number, got `{}`", m.at(k.line), k.key, k.args.join(" "))),
    }
}

/// Build `m`'s BRDF from its own keys.
///
/// # Errors
/// A used key whose value cannot be read or is out of range, named by `file:line`.
pub fn bsdf_from_mtl(m: &MtlMaterial) -> Result<AuthoredBsdf, String> {
    let mut notes = Vec::new();
    let mut used: Vec<&str> = vec!["Kd"];
    let base = m.get("Kd").map(|k| band(m, k)).transpose()?.unwrap_or(1.0);
    let pbr = ["Pr", "Pm", "map_Pr", "map_Pm"].iter().any(|k| m.get(k).is_some());
    // `map_Pr` and `map_Pm`: one channel (the first; a grey image's), linear, times `Pr`, `Pm`.
    let mut value_maps = [None, None];
    let bsdf = if pbr {
        used.extend(["Pr", "Pm", "Ni", "map_Pr", "map_Pm"]);
        let mut roughness = match m.get("Pr") {
            Some(k) => unit(m, k, scalar(m, k)?)?,
            None => 1.0,
        };
        let rough_factor = roughness;
        if roughness < MIN_ROUGHNESS {
            let k = m.get("Pr").expect("Pr below 1 was given");
            notes.push(format!(
                "`Pr` {roughness} raised to {MIN_ROUGHNESS}, the smoothest GGX hilcam takes: {}",
                m.at(k.line)
            ));
            roughness = MIN_ROUGHNESS;
        }
        let metallic = match m.get("Pm") {
            Some(k) => unit(m, k, scalar(m, k)?)?,
            None => 0.0,
        };
        let metal_factor = if m.get("Pm").is_some() { metallic } else { 1.0 };
        let mut ior = crate::render::bsdf::GLTF_DIELECTRIC_IOR;
        if let Some(k) = m.get("Ni") {
            let v = scalar(m, k)?;
            if (1.0..=4.0).contains(&v) {
                ior = v;
            } else if metallic < 1.0 {
                notes.push(format!("`Ni` {v} is outside [1, 4]: 1.5 used: {}", m.at(k.line)));
            }
        }
        for key in ["Ks", "Ns"] {
            if let Some(k) = m.get(key) {
                notes.push(format!("`{key}` ignored (the material has `Pr`/`Pm`): {}", m.at(k.line)));
            }
        }
        used.extend(["Ks", "Ns"]);
        for (slot, (key, factor)) in value_maps.iter_mut().zip([("map_Pr", rough_factor), ("map_Pm", metal_factor)]) {
            if let Some(k) = m.get(key) {
                *slot = Some(TextureRef { channel: Some(0), ..map_file(m, k, [factor; 3], &mut notes)? });
            }
        }
        metallic_roughness_textured(base, metallic, roughness, ior, value_maps[1].is_some())
            .map_err(|e| format!("{}: {e}", m.at(m.line)))?
    } else {
        used.extend(["Ks", "Ns"]);
        let ks = m.get("Ks").map(|k| band(m, k)).transpose()?.unwrap_or(0.0);
        if let Some(k) = m.get("Ni") {
            notes.push(format!("`Ni` ignored (refraction; no `Pr`/`Pm`): {}", m.at(k.line)));
        }
        used.push("Ni");
        if ks == 0.0 {
            if let Some(k) = m.get("Ns") {
                notes.push(format!("`Ns` ignored (`Ks` is black): {}", m.at(k.line)));
            }
            Bsdf::Lambert(Lambert::new(base).map_err(|e| format!("{}: {e}", m.at(m.line)))?)
        } else {
            let mut f0 = ks;
            if f0 > MAX_DIELECTRIC_F0 {
                let k = m.get("Ks").expect("Ks above 0 was given");
                notes.push(format!(
                    "`Ks` {ks} is above a dielectric coating's F0 ({MAX_DIELECTRIC_F0} at index 4): {MAX_DIELECTRIC_F0} used \
                     (`Pm 1` makes a metal): {}",
                    m.at(k.line)
                ));
                f0 = MAX_DIELECTRIC_F0;
            }
            let ns = match m.get("Ns") {
                Some(k) => {
                    let v = scalar(m, k)?;
                    if v < 0.0 {
                        return Err(format!("{}: Ns: {v} must be ≥ 0", m.at(k.line)));
                    }
                    v
                }
                None => 0.0,
            };
            let alpha = (2.0 / (ns + 2.0)).sqrt();
            let roughness = alpha.sqrt().max(MIN_ROUGHNESS);
            let ior = ((1.0 + f0.sqrt()) / (1.0 - f0.sqrt())).min(4.0); // f32 rounding at F0 0.36
            Bsdf::Ggx(Ggx::plastic(roughness, base, ior).map_err(|e| format!("{}: {e}", m.at(m.line)))?)
        }
    };
    let emission = emission(m, &mut notes)?;
    used.extend(["Ke", "map_Ke"]);
    let base_texture = m.get("map_Kd").map(|k| map_file(m, k, kd_factor(m)?, &mut notes)).transpose()?;
    used.push("map_Kd");
    // `norm`: a tangent-space normal map (the PBR extension's), r g b linear.
    let normal_texture = m.get("norm").map(|k| map_file(m, k, [1.0; 3], &mut notes)).transpose()?.map(|t| (t, 1.0));
    used.push("norm");
    // Every other key, once per material.
    let mut reported: Vec<&str> = Vec::new();
    for k in &m.keys {
        if !used.contains(&k.key.as_str()) && !reported.contains(&k.key.as_str()) {
            reported.push(&k.key);
            notes.push(format!("`{}` ignored: {}", k.key, m.at(k.line)));
        }
    }
    let [roughness_texture, metallic_texture] = value_maps;
    Ok(AuthoredBsdf { bsdf, notes, base_texture, emission, roughness_texture, metallic_texture, normal_texture })
}

/// `Kd`'s r g b, the factor of `map_Kd` (white without `Kd`).
fn kd_factor(m: &MtlMaterial) -> Result<[f32; 3], String> {
    Ok(match m.get("Kd") {
        None => [1.0; 3],
        Some(kd) => match kd.args.iter().map(|a| a.parse::<f32>()).collect::<Result<Vec<_>, _>>() {
            Ok(v) if v.len() == 3 => [v[0], v[1], v[2]],
            Ok(v) if v.len() == 1 => [v[0]; 3],
            _ => [band(m, kd)?; 3],
        },
    })
}

/// `map_Kd [options] file` (or `map_Ke`): the image beside the MTL (sRGB), times
/// `factor`. Options (`-s`, `-o`, `-bm`, …) are noted as ignored and the file is the last
/// word.
fn map_file(m: &MtlMaterial, k: &MtlKey, factor: [f32; 3], notes: &mut Vec<String>) -> Result<TextureRef, String> {
    let file = match k.args.as_slice() {
        [] => return Err(format!("{}: {}: needs a file name", m.at(k.line), k.key)),
        args if args.iter().any(|a| a.starts_with('-')) => {
            notes.push(format!(
                "`{}` options `{}` ignored (the image is used as is): {}",
                k.key,
                args[..args.len() - 1].join(" "),
                m.at(k.line)
            ));
            args[args.len() - 1].clone()
        }
        args => args.join(" "),
    };
    let dir = m.file.parent().unwrap_or(std::path::Path::new("."));
    Ok(TextureRef {
        source: ImageSource::File(dir.join(file.replace('\\', "/"))),
        factor,
        channel: None,
        at: m.at(k.line),
    })
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::render::bsdf::ConductorFresnel;
    use crate::scene::mtl::parse_mtl;
    use std::path::Path;

    fn one(text: &str) -> Result<AuthoredBsdf, String> {
        let m = parse_mtl(Path::new("/x/panel.mtl"), &format!("newmtl panel\n{text}"));
        bsdf_from_mtl(&m[0])
    }

    #[test]
    fn kd_alone_is_lambert_of_the_band_mean() {
        let f = one("Kd 0.2 0.5 0.8\n").unwrap();
        assert_eq!(f.bsdf.is_lambertian(), Some(0.5));
        assert!(f.notes.is_empty(), "{:?}", f.notes);
        assert_eq!(one("Kd 0.3\n").unwrap().bsdf.is_lambertian(), Some(0.3));
    }

    #[test]
    fn pbr_keys_choose_the_ggx_form() {
        let Bsdf::Ggx(c) = one("Kd 0.9 0.9 0.9\nPr 0.5\nPm 1\n").unwrap().bsdf else { panic!() };
        let ConductorFresnel::Schlick { f0 } = c.conductor else { panic!() };
        assert_eq!((c.metallic, c.dist.alpha), (1.0, 0.25));
        assert!((f0 - 0.9).abs() < 1e-6, "{f0}");
        let Bsdf::Ggx(p) = one("Kd 0.4 0.4 0.4\nPr 0.3\nPm 0\nNi 1.6\n").unwrap().bsdf else { panic!() };
        assert_eq!((p.metallic, p.rho, p.eta), (0.0, 0.4, 1.6));
        assert!((p.dist.alpha - 0.09).abs() < 1e-7);
        let Bsdf::Ggx(b) = one("Kd 0.5 0.5 0.5\nPm 0.25\n").unwrap().bsdf else { panic!() };
        assert_eq!((b.metallic, b.dist.alpha), (0.25, 1.0));
    }

    #[test]
    fn ks_and_ns_make_a_coating() {
        // Ks 0.04 → η 1.5; Ns 198 → α = √(2/200) = 0.1.
        let Bsdf::Ggx(p) = one("Kd 0.5 0.5 0.5\nKs 0.04 0.04 0.04\nNs 198\n").unwrap().bsdf else { panic!() };
        assert!((p.eta - 1.5).abs() < 1e-5 && (p.dist.alpha - 0.1).abs() < 1e-6, "{p:?}");
        // `Ks 1 1 1` (an exporter's default) is clamped, and said so.
        let f = one("Kd 0.8 0.8 0.8\nKs 1 1 1\nNs 10\n").unwrap();
        assert!(
            f.notes.iter().any(|n| n.starts_with("`Ks` 1 is above") && n.ends_with("panel.mtl:3")),
            "{:?}",
            f.notes
        );
    }

    #[test]
    fn every_unused_key_is_named_once_with_file_and_line() {
        let f = one("Kd 0.5 0.5 0.5\nmap_Ks cells.png\nPs 0.3\nillum 2\nd 1\nPs 0.4\nKa 0 0 0\nKe 1 1 1\n").unwrap();
        for want in [
            "`map_Ks` ignored: panel.mtl:3",
            "`Ps` ignored: panel.mtl:4",
            "`illum` ignored: panel.mtl:5",
            "`d` ignored: panel.mtl:6",
            "`Ka` ignored: panel.mtl:8",
        ] {
            assert!(f.notes.iter().any(|n| n == want), "missing {want}: {:?}", f.notes);
        }
        assert_eq!(f.notes.iter().filter(|n| n.contains("`Ps`")).count(), 1);
        assert!(!f.notes.iter().any(|n| n.contains("`Ke`")), "Ke is used: {:?}", f.notes);
        let f = one("Kd 0.5 0.5 0.5\nKs 0.5 0.5 0.5\nPr 0.5\nNi 1.45\n").unwrap();
        assert!(f.notes.iter().any(|n| n == "`Ks` ignored (the material has `Pr`/`Pm`): panel.mtl:3"), "{:?}", f.notes);
    }

    #[test]
    fn ke_is_emission_relative_to_sunlit_white_and_map_ke_its_texture() {
        let e = one("Kd 0.5\nKe 0.2 0.4 3.0\n").unwrap().emission.unwrap();
        assert!((e.relative - 1.2).abs() < 1e-6 && e.texture.is_none(), "{e:?}");
        assert!(one("Kd 0.5\nKe 0 0 0\n").unwrap().emission.is_none());
        assert!(one("Kd 0.5\n").unwrap().emission.is_none());
        let e = one("Ke 0.5 1 1.5\nmap_Ke glow.png\n").unwrap().emission.unwrap();
        let t = e.texture.unwrap();
        assert_eq!((e.relative, t.factor, t.at.as_str()), (1.0, [0.5, 1.0, 1.5], "panel.mtl:3"));
        let f = one("Ke 0 0 0\nmap_Ke glow.png\n").unwrap();
        assert!(f.emission.is_none());
        assert!(
            f.notes.iter().any(|n| n == "`map_Ke` `/x/glow.png` ignored: `Ke` is black: panel.mtl:3"),
            "{:?}",
            f.notes
        );
        assert!(one("Ke -1 0 0\n").unwrap_err().starts_with("panel.mtl:2: Ke: `-1 0 0` must be in [0, "));
        assert!(one("Ke a\n").unwrap_err().starts_with("panel.mtl:2: Ke:"));
    }

    #[test]
    fn map_kd_is_the_image_beside_the_mtl_times_kd() {
        let f = one("Kd 0.2 0.4 0.6\nmap_Kd -s 2 2 1 tex\\cells.png\n").unwrap();
        let t = f.base_texture.unwrap();
        assert_eq!(t.source, ImageSource::File("/x/tex/cells.png".into()));
        assert_eq!((t.factor, t.at.as_str()), ([0.2, 0.4, 0.6], "panel.mtl:3"));
        assert!(
            f.notes.iter().any(|n| n == "`map_Kd` options `-s 2 2 1` ignored (the image is used as is): panel.mtl:3")
        );
        assert_eq!(one("map_Kd a b.png\n").unwrap().base_texture.unwrap().factor, [1.0; 3]);
        assert!(one("Kd 0.5\nmap_Kd\n").unwrap_err().starts_with("panel.mtl:3: map_Kd"));
    }

    #[test]
    fn bad_values_are_errors_naming_file_line_and_key() {
        for (text, want) in [
            ("Kd 0.5 x 0.5\n", "panel.mtl:2: Kd:"),
            ("Kd 1.5 1.5 1.5\n", "panel.mtl:2: Kd: 1.5 must be in [0, 1]"),
            ("Kd 0.5\nPr nan\n", "panel.mtl:3: Pr:"),
            ("Kd 0.5\nPm 2\n", "panel.mtl:3: Pm: 2 must be in [0, 1]"),
            ("Kd 0.5\nKs 0.1\nNs -3\n", "panel.mtl:4: Ns:"),
        ] {
            let e = one(text).unwrap_err();
            assert!(e.starts_with(want), "{text:?}: {e}");
        }
    }
}
