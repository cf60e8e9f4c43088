//! `hilcam brdf`: tabulate, plot and check the BRDF models for gold polyimide.
//!
//! In-plane geometry: the light is at `θi` on the −x side, `wi = (−sin θi, 0, cos θi)`; the
//! view angle `θv` is signed, `wo = (sin θv, 0, cos θv)`, so the mirror direction is
//! `θv = +θi` (the forward-scatter side is positive), as in the paper's Fig. 6.

use crate::plot::{Legend, LineChart, Scale, Series};
use anyhow::Context;
use glam::Vec3;
use hilcam_core::render::bsdf::{BlinnPhong, Bsdf, CookTorrance, ImprovedBlinnPhong, Lambert};
use std::fmt::Write as _;
use std::path::PathBuf;

/// Arguments of `hilcam brdf`.
#[derive(clap::Args, Debug)]
pub struct BrdfArgs {
    /// PNG with f_r against view angle at θi = 30° and 60° (log y axis).
    #[arg(long, default_value = "brdf.png")]
    pub out: PathBuf,
    /// Also write the full-resolution curves as CSV.
    #[arg(long)]
    pub csv: Option<PathBuf>,
    /// View-angle step of the curves, degrees.
    #[arg(long, default_value_t = 0.1)]
    pub step_deg: f64,
    /// Samples per directional-albedo estimate (stratified).
    #[arg(long, default_value_t = 65_536)]
    pub albedo_samples: u32,
}

/// The models compared, in display order: (name, model, dashed in the plot).
pub fn gold_models() -> Vec<(&'static str, Bsdf, bool)> {
    let [d, s, a] = BlinnPhong::GOLD_POLYIMIDE_FIT;
    let bp = BlinnPhong::new(d, s, a).expect("preset valid");
    let [d, m, f0, ks] = CookTorrance::GOLD_POLYIMIDE_FIT;
    let ct = CookTorrance::new(d, m, f0, ks).expect("preset valid");
    let imp = ImprovedBlinnPhong::gold_polyimide();
    vec![
        ("improved Blinn-Phong (paper)", Bsdf::ImprovedBlinnPhong(imp), false),
        ("improved Blinn-Phong normalized", Bsdf::ImprovedBlinnPhong(imp.normalized()), true),
        ("Blinn-Phong Eq.4 (fit)", Bsdf::BlinnPhong(bp), false),
        ("Blinn-Phong Eq.4 normalized", Bsdf::BlinnPhong(bp.normalized()), true),
        ("Cook-Torrance (fit)", Bsdf::CookTorrance(ct), false),
        ("Cook-Torrance normalized", Bsdf::CookTorrance(ct.normalized()), true),
        ("Lambert rho=0.3717", Bsdf::Lambert(Lambert::new(0.3717).expect("valid")), false),
    ]
}

/// `(wo, wi)` for incidence `theta_i` and signed view angle `theta_v` (degrees).
pub fn in_plane(theta_i: f64, theta_v: f64) -> (Vec3, Vec3) {
    let (ti, tv) = (theta_i.to_radians(), theta_v.to_radians());
    let wi = Vec3::new(-ti.sin() as f32, 0.0, ti.cos() as f32);
    let wo = Vec3::new(tv.sin() as f32, 0.0, tv.cos() as f32);
    (wo, wi)
}

/// RMS difference between two models' in-plane curves at `theta_i` over θv ∈ [−89°, 89°]
/// (0.25° steps), in sr⁻¹ — the measure of the paper's Table 2.
pub fn curve_rmse(a: &Bsdf, b: &Bsdf, theta_i: f64) -> f64 {
    let (mut s, mut n) = (0.0, 0.0);
    for k in 0..=712 {
        let tv = -89.0 + 0.25 * f64::from(k);
        let (wo, wi) = in_plane(theta_i, tv);
        let d = f64::from(a.eval(wo, wi)) - f64::from(b.eval(wo, wi));
        s += d * d;
        n += 1.0;
    }
    (s / n).sqrt()
}

fn views(step: f64) -> Vec<f64> {
    let n = (178.0 / step).round() as i64;
    (0..=n).map(|k| -89.0 + 178.0 * k as f64 / n as f64).collect()
}

/// Run the command.
pub fn run(args: BrdfArgs) -> anyhow::Result<()> {
    anyhow::ensure!(args.step_deg > 0.0 && args.step_deg <= 10.0, "--step-deg must be in (0, 10]");
    let models = gold_models();
    let mut out = String::new();

    // 1. f_r against view angle, coarse table (the plot and CSV have the full curves).
    for ti in [30.0, 60.0] {
        writeln!(out, "\nf_r (1/sr) at theta_i = {ti} deg, in the plane of incidence (mirror at theta_v = +{ti})")?;
        write!(out, "{:>8}", "theta_v")?;
        for (name, _, _) in &models {
            write!(out, " {:>12}", short(name))?;
        }
        writeln!(out)?;
        let mut tvs: Vec<f64> = (-8..=8).map(|k| f64::from(k) * 10.0).collect();
        tvs.extend([-4.0, -2.0, -1.0, -0.5, 0.5, 1.0, 2.0, 4.0].map(|d| ti + d));
        tvs.sort_by(f64::total_cmp);
        tvs.dedup();
        for tv in tvs {
            let (wo, wi) = in_plane(ti, tv);
            write!(out, "{tv:>8.1}")?;
            for (_, b, _) in &models {
                write!(out, " {:>12.4}", b.eval(wo, wi))?;
            }
            writeln!(out)?;
        }
    }

    // 2. Directional albedo ∫ f_r cosθi dωi for a view direction θo.
    writeln!(out, "\ndirectional albedo (fraction of light from all directions reflected toward theta_o)")?;
    write!(out, "{:<34}", "model")?;
    for th in [0.0, 30.0, 60.0, 85.0] {
        write!(out, " {:>9}", format!("{th}deg"))?;
    }
    writeln!(out, "  note")?;
    for (name, b, _) in &models {
        write!(out, "{name:<34}")?;
        let mut over = false;
        for th in [0.0f32, 30.0, 60.0, 85.0] {
            let a = b.directional_albedo(th.to_radians().cos(), args.albedo_samples);
            over |= a > 1.0;
            write!(out, " {a:>9.4}")?;
        }
        let note = match b {
            Bsdf::ImprovedBlinnPhong(m) if m.normalization < 1.0 => {
                format!("rho_s scaled x{:.4}", m.normalization)
            }
            Bsdf::BlinnPhong(m) if m.normalization < 1.0 => {
                format!("rho_s scaled x{:.4}", m.normalization)
            }
            Bsdf::CookTorrance(m) if m.normalization < 1.0 => {
                format!("k_s scaled x{:.4}", m.normalization)
            }
            _ => String::new(),
        };
        writeln!(out, "  {}{note}", if over { "ALBEDO > 1 (not energy-conserving) " } else { "" })?;
    }

    // 3. Fit quality against the paper's model (cf. the paper's Table 2, which is against
    //    the measured BRDF; the measurements are not published, Eq. 5 stands in for them).
    let paper = models[0].1;
    writeln!(out, "\nRMSE (1/sr) of each model's curve against the paper's improved Blinn-Phong")?;
    writeln!(out, "{:<34} {:>9} {:>9}", "model", "30deg", "60deg")?;
    for (name, b, _) in models.iter().skip(1) {
        writeln!(out, "{name:<34} {:>9.3} {:>9.3}", curve_rmse(&paper, b, 30.0), curve_rmse(&paper, b, 60.0))?;
    }
    print!("{out}");

    // 4. Curves: plot (two charts stacked) and CSV.
    let tvs = views(args.step_deg);
    let mut charts = Vec::new();
    // Full range on the left, ±8° around the mirror direction on the right.
    let panels = |ti: f64| {
        [
            (-90.0, 90.0, Legend::UpperLeft, "full range"),
            (ti - 8.0, ti + 8.0, Legend::Hidden, "near the mirror direction"),
        ]
    };
    let mut csv = String::from("theta_i_deg,theta_v_deg");
    for (name, _, _) in &models {
        write!(csv, ",\"{name}\"")?;
    }
    csv.push('\n');
    for ti in [30.0, 60.0] {
        for (lo, hi, legend, what) in panels(ti) {
            let mut chart = LineChart::new(format!("gold polyimide BRDF, theta_i = {ti} deg, {what}"))
                .x_label("view angle theta_v (deg), mirror at +theta_i")
                .y_label("f_r (1/sr)")
                .scales(Scale::Linear, Scale::Log)
                .x_range(lo, hi)
                .y_range(0.05, 2000.0)
                .legend(legend)
                .size(800, 560);
            let step = args.step_deg.min((hi - lo) / 400.0);
            let n = ((hi - lo) / step).round() as i64;
            for (name, b, dashed) in &models {
                let pts: Vec<(f64, f64)> = (0..=n)
                    .map(|k| {
                        let tv = lo + (hi - lo) * k as f64 / n as f64;
                        let (wo, wi) = in_plane(ti, tv.clamp(-89.99, 89.99));
                        (tv, f64::from(b.eval(wo, wi)))
                    })
                    .collect();
                let s = Series::new(*name, pts);
                chart = chart.series(if *dashed { s.dashed() } else { s });
            }
            charts.push(chart.render().with_context(|| format!("drawing the theta_i = {ti} chart"))?);
        }
        for &tv in &tvs {
            let (wo, wi) = in_plane(ti, tv);
            write!(csv, "{ti},{tv:.4}")?;
            for (_, b, _) in &models {
                write!(csv, ",{:e}", b.eval(wo, wi))?;
            }
            csv.push('\n');
        }
    }
    // 2 × 2 grid: rows θi = 30°, 60°; columns full range, zoom.
    let (w, h) = charts[0].dimensions();
    let mut img = image::RgbImage::new(2 * w, 2 * h);
    for (k, c) in charts.iter().enumerate() {
        image::imageops::replace(&mut img, c, i64::from(w) * (k % 2) as i64, i64::from(h) * (k / 2) as i64);
    }
    img.save_with_format(&args.out, image::ImageFormat::Png)
        .with_context(|| format!("writing {}", args.out.display()))?;
    println!("\nwrote {}", args.out.display());
    if let Some(p) = &args.csv {
        std::fs::write(p, csv).with_context(|| format!("writing {}", p.display()))?;
        println!("wrote {}", p.display());
    }
    Ok(())
}

fn short(name: &str) -> String {
    let s: String = name
        .replace("improved Blinn-Phong", "impBP")
        .replace("Blinn-Phong Eq.4", "BP")
        .replace("Cook-Torrance", "CT")
        .replace(" normalized", " norm")
        .replace(" (paper)", " paper")
        .replace(" (fit)", " fit");
    s.chars().take(12).collect()
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn in_plane_mirror_is_at_plus_theta_i() {
        let (wo, wi) = in_plane(30.0, 30.0);
        let h = (wo + wi).normalize();
        assert!((h - Vec3::Z).length() < 1e-6);
    }

    #[test]
    fn run_writes_png_and_csv() {
        let dir = tempfile::tempdir().unwrap();
        let (png, csv) = (dir.path().join("b.png"), dir.path().join("b.csv"));
        run(BrdfArgs { out: png.clone(), csv: Some(csv.clone()), step_deg: 2.0, albedo_samples: 256 }).unwrap();
        let img = image::open(&png).unwrap();
        assert_eq!((img.width(), img.height()), (1600, 1120));
        let text = std::fs::read_to_string(&csv).unwrap();
        // Header + 2 incidence angles × 90 view angles.
        assert_eq!(text.lines().count(), 1 + 2 * 90);
    }
}
