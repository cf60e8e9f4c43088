"""hilcam vs Mitsuba 3 at equal sensor criterion (issue 36): `vs_mitsuba.py --criterion`.

For each spp of a ladder, both renderers render one pose with --seeds seeds (alternating,
in rotating order). Every radiance frame goes through the scene camera's sensor chain to
photo-charge by `hilcam bench charge` — the conversion `hilcam bench quality` judges with
(τ cos⁴, PSF, e⁻ per unit radiance at the auto-exposure settled on the scene's own frames,
clipped at the full well). Per renderer and spp, the judge (`judge`, the definition of
crates/hilcam-lab/src/bench/quality.rs `judge`) counts the share of lit pixels (reference
≥ 1 e⁻) whose standard deviation over the seeds exceeds 0.5 σ_cam, σ_cam² = signal + dark +
read² + gain²/12 at the reference's signal. The time at which each renderer's curve reaches
a share is interpolated log–log between the measured spp that bracket it; the ratio
Mitsuba time / hilcam time is printed per share (> 1: hilcam is faster).

`check_criterion` runs `hilcam bench quality --dump` and recounts its frames with the same
conversion and judge: the counts must be equal (exit 1 otherwise), so the share printed
here and `bench quality`'s are one definition.
"""

from __future__ import annotations

import csv
import math
import statistics
import subprocess
from pathlib import Path

from vs_mitsuba import (
    OUT_DIR,
    ExportError,
    Hilcam,
    interp_time,
    label,
    log,
    mitsuba_samplers,
    make_renderers,
    timed,
    write_csv,
)

K = 0.5
TARGETS = (0.20, 0.10, 0.05)


# ---------------------------------------------------------------------------------------
# The conversion (hilcam bench charge) and the judge.
# ---------------------------------------------------------------------------------------


def write_pfm(path: Path, img) -> None:
    """A greyscale little-endian PFM, rows bottom-to-top (what hilcam's reader takes)."""
    import numpy as np

    a = np.ascontiguousarray(np.flipud(np.asarray(img, dtype="<f4")))
    h, w = a.shape
    with path.open("wb") as f:
        f.write(f"Pf\n{w} {h}\n-1.0\n".encode())
        f.write(a.tobytes())


class Charge:
    """Radiance → photo-charge through the scene camera's sensor chain, by `hilcam bench
    charge` (the integration time settled once, then passed back with every digit)."""

    def __init__(self, exe: Path, scene: Path, width: int):
        self.exe, self.scene, self.width = exe, scene, width
        self.consts: dict[str, float] | None = None

    def __call__(self, frames: list[Path]):
        """Each frame's photo-charge (e⁻, float64, H × W), in order."""
        import numpy as np

        cmd = [str(self.exe), "--log", "warn", "bench", "charge", "--scene", str(self.scene), "--width", str(self.width)]
        if self.consts is not None:
            cmd += ["--integration-s", repr(self.consts["integration_s"])]
        r = subprocess.run(cmd + [str(f) for f in frames], capture_output=True, text=True, check=False)
        if r.returncode != 0:
            raise RuntimeError(f"hilcam bench charge failed: {' '.join(cmd[:9])} …\n{r.stderr}")
        consts = {}
        for ln in r.stdout.splitlines():
            w = ln.split()
            if len(w) == 2 and w[0] in ("integration_s", "e_per_radiance", "full_well_e", "floor_e2", "quant_e2", "k"):
                consts[w[0]] = float(w[1])
        if self.consts is None:
            self.consts = consts
            auto = next((ln for ln in r.stdout.splitlines() if ln.startswith("auto-exposure")), "")
            log(f"sensor chain of {self.scene.name} at {self.width} px: {auto}; " + ", ".join(f"{k} {v:.6g}" for k, v in consts.items()))
        elif consts != self.consts:
            raise RuntimeError(f"hilcam bench charge: the conversion changed between calls ({consts} vs {self.consts})")
        out = []
        for f in frames:
            e = np.fromfile(f.with_suffix(".e64"), dtype="<f8")
            out.append(e.reshape(-1, self.width) if e.size % self.width == 0 else e)
            f.with_suffix(".e64").unlink()
        return out

    def camera_e2(self, signal):
        """σ_cam², e⁻² (bench::quality::Conversion::camera_e2, same order of operations)."""
        import numpy as np

        c = self.consts
        return np.maximum(signal, 0.0) + c["floor_e2"] + c["quant_e2"]


class Sums:
    """Per-pixel running sums over seeds (bench::quality::SeedSums: frames added in order)."""

    def __init__(self):
        self.n, self.s, self.q = 0, None, None

    def add(self, e):
        e = e.ravel()
        if self.s is None:
            import numpy as np

            self.s, self.q = np.zeros_like(e), np.zeros_like(e)
        self.s += e
        self.q += e * e
        self.n += 1

    def mean(self):
        return self.s / max(self.n, 1)

    def variance(self):
        import numpy as np

        if self.n < 2:
            return np.zeros_like(self.s)
        n = float(self.n)
        m = self.s / n
        return np.maximum((self.q - n * m * m) / (n - 1.0), 0.0)


def reference_from(sums: Sums):
    """(mean, variance of the mean) from independent chunks (Reference::from_chunks)."""
    return sums.mean(), sums.variance() / float(max(sums.n, 1))


def judge(sums: Sums, ref_mean, ref_var, camera_e2, k: float = K) -> dict:
    """bench::quality::judge's counts: lit = reference ≥ 1 e⁻; above_noise: σ²_seed >
    k²σ²_cam; above_error: σ²_seed + bias² > k²σ²_cam (bias² = (mean − ref)² − σ²_seed/N −
    σ²_ref, ≥ 0); mean_bias = Σ mean / Σ ref − 1 over lit pixels."""
    import numpy as np

    n = float(max(sums.n, 1))
    m, var = sums.mean(), sums.variance()
    lit = ref_mean >= 1.0
    d = m - ref_mean
    bias2 = np.maximum(d * d - var / n - ref_var, 0.0)
    cam = camera_e2(ref_mean)
    bound = k * k * cam
    nl = int(lit.sum())
    return {
        "lit": nl,
        "above_noise": int((var > bound)[lit].sum()),
        "above_error": int((var + bias2 > bound)[lit].sum()),
        "noise_share": float((var > bound)[lit].sum() / max(nl, 1)),
        "error_share": float((var + bias2 > bound)[lit].sum() / max(nl, 1)),
        "rms_noise_ratio": float(np.sqrt(np.mean(var[lit] / cam[lit]))) if nl else 0.0,
        "mean_bias": float(m[lit].sum() / ref_mean[lit].sum() - 1.0) if nl else 0.0,
    }


# ---------------------------------------------------------------------------------------
# The check: the same count as `hilcam bench quality` on its own frames.
# ---------------------------------------------------------------------------------------


def check_criterion(args, scene: Path, width: int, exe: Path, tmp: Path) -> bool:
    """Run `hilcam bench quality --dump` (row fixed:4, --seeds seeds, the scene's own camera
    and settings, a small reference) and recount its frames here: conversion by `hilcam
    bench charge`, judged by `judge`. True when lit, above-noise and above-error counts are
    equal and the mean bias agrees to the CSV's 6 decimals."""
    import numpy as np

    d = tmp / "quality-check"
    cmd = [
        str(exe), "--log", "warn", "bench", "quality", "--scene", str(scene), "--width", str(width),
        "--rows", "fixed:4", "--seeds", str(args.seeds), "--reference-spp", "64", "--reference-chunks", "4",
        "--cache", str(d / "cache"), "--out", str(d / "quality"), "--dump", str(d / "dump"),
    ]  # fmt: skip
    r = subprocess.run(cmd, capture_output=True, text=True, check=False)
    if r.returncode != 0:
        raise RuntimeError(f"{' '.join(cmd)}\n{r.stderr}")
    with (d / "quality.csv").open() as f:
        row = next(csv.DictReader(f))
    raw = (d / "dump" / "reference.bin").read_bytes()
    w, h = (int(v) for v in np.frombuffer(raw[:8], dtype="<u4"))
    vals = np.frombuffer(raw[16:], dtype="<f8")
    ref_mean, ref_var = vals[: w * h], vals[w * h :]
    charge = Charge(exe, scene, width)
    frames = sorted((d / "dump" / "fixed_4").glob("seed*.pfm"))
    sums = Sums()
    for e in charge(frames):
        sums.add(e)
    j = judge(sums, ref_mean, ref_var, charge.camera_e2)
    lit = int(row["lit"])
    theirs = (lit, round(float(row["noise_share"]) * lit), round(float(row["error_share"]) * lit))
    ours = (j["lit"], j["above_noise"], j["above_error"])
    bias_ok = abs(j["mean_bias"] - float(row["mean_bias"])) <= 1e-6
    ok = theirs == ours and bias_ok and len(frames) == args.seeds
    log(
        f"  [{'ok' if ok else 'FAIL'}] criterion = `hilcam bench quality`'s ({scene.name} {w}x{h}, row fixed:4, "
        f"{len(frames)} seeds): lit / above 0.5 σ_cam (noise) / (error) here {ours[0]} / {ours[1]} / {ours[2]}, "
        f"bench quality {theirs[0]} / {theirs[1]} / {theirs[2]}; noise share {j['noise_share'] * 100:.3f} % vs "
        f"{float(row['noise_share']) * 100:.3f} %; mean bias {j['mean_bias']:+.6f} vs {float(row['mean_bias']):+.6f}"
    )
    return ok


# ---------------------------------------------------------------------------------------
# The benchmark.
# ---------------------------------------------------------------------------------------


def bench_criterion(args, mi, np, sensor_scene: Path, hilcam_file: Path, sc, depth: int, tmp: Path, exe: Path):
    """Render the spp ladder with --seeds seeds per renderer, alternating; judge each
    (renderer, spp) by the sensor criterion; print the equal-criterion time ratios."""
    cam = sc.camera.scaled(args.width, args.height)
    tag = f"{sensor_scene.stem}_{cam.width}x{cam.height}_d{depth}_criterion_{'+'.join(args.sampler)}"
    h, h_uniform, ms = make_renderers(args, mi, np, hilcam_file, sc, cam, depth, tmp, exe)
    charge = Charge(exe, sensor_scene, cam.width)
    log(
        f"\n== equal sensor criterion: {sensor_scene.name} (rendered as a pinhole by both), {cam.width}x{cam.height}, "
        f"depth {depth}, {args.seeds} seeds per renderer and spp; hilcam {args.hilcam_sequence} + {args.hilcam_sampler}, "
        f"Mitsuba {', '.join(args.sampler)}; roulette {'on' if args.roulette else 'off'} in both; {load()}"
    )

    # The reference: chunks of hilcam (every pixel alike) and of Mitsuba, in photo-charge.
    t0 = time_now()
    halves = {"hilcam": Sums(), "mitsuba": Sums()}
    frames, who = [], []
    for c in range(args.ref_chunks):
        img, _ = h_uniform.render(args.ref_spp, seed=1_000_003 + c)
        p = tmp / f"ref_h{c}.pfm"
        write_pfm(p, img)
        frames.append(p)
        who.append("hilcam")
        img, _ = ms[args.sampler[0]].render_passes(args.ref_spp, 2_000_003 + 100_003 * c, args.ref_pass_spp)
        p = tmp / f"ref_m{c}.pfm"
        write_pfm(p, img)
        frames.append(p)
        who.append("mitsuba")
    ref_all = Sums()
    for name, e in zip(who, charge(frames)):
        halves[name].add(e)
        ref_all.add(e)
    ref_mean, ref_var = reference_from(ref_all)
    lit = ref_mean >= 1.0
    hm, mm = halves["hilcam"].mean(), halves["mitsuba"].mean()
    halves_diff = float(hm[lit].sum() / mm[lit].sum() - 1.0)
    log(
        f"reference: {args.ref_chunks} chunks of {args.ref_spp} spp from each renderer (hilcam --no-adaptive, Mitsuba "
        f"{args.sampler[0]}), {2 * args.ref_chunks * args.ref_spp} spp per pixel in photo-charge, its variance from the "
        f"chunks; {int(lit.sum())} lit pixels (≥ 1 e⁻); hilcam's half / Mitsuba's half − 1 = {halves_diff * 100:+.3f} % "
        f"over lit pixels ({time_now() - t0:.0f} s)"
    )

    renderers = [("hilcam", args.hilcam_sequence, h)] + [("mitsuba", smp, m) for smp, m in ms.items()]
    rows = []
    for spp in sorted(set(args.spp)):
        sums = {(n, smp): Sums() for n, smp, _ in renderers}
        times: dict = {key: [] for key in sums}
        files: dict = {key: [] for key in sums}
        for s in range(args.seeds):
            k = s % len(renderers)
            for name, smp, r in renderers[k:] + renderers[:k]:
                if not timed(name, smp, spp):
                    continue
                # The first --reps seeds are timed, for every renderer in the same rounds (each
                # hilcam frame is its own process: those few run warm, after an untimed frame).
                warm = s < args.reps
                if isinstance(r, Hilcam):
                    img, t = r.render(spp, 1 + s, warm=warm)
                else:
                    img, t = r.render(spp, 1 + s)
                if warm:
                    times[(name, smp)].append(t)
                p = tmp / f"{name}_{smp}_{spp}_{s:02}.pfm"
                write_pfm(p, img)
                files[(name, smp)].append(p)
        keys = [key for key in sums if files[key]]
        charged = charge([p for key in keys for p in files[key]])
        at = 0
        for key in keys:
            for e in charged[at : at + len(files[key])]:
                sums[key].add(e)
            at += len(files[key])
            for p in files[key]:
                p.unlink()
            j = judge(sums[key], ref_mean, ref_var, charge.camera_e2)
            rows.append({
                "scene": sensor_scene.stem, "width": cam.width, "height": cam.height, "depth": depth,
                "renderer": key[0], "sampler": key[1], "spp": spp, "seeds": sums[key].n,
                "time_s": statistics.median(times[key]), "timed_frames": len(times[key]),
                **{k2: j[k2] for k2 in ("lit", "above_noise", "noise_share", "error_share", "rms_noise_ratio", "mean_bias")},
                "ref_halves_diff": halves_diff,
            })  # fmt: skip
        cur = [r for r in rows if r["spp"] == spp]
        log(f"  spp {spp:>4}: " + "   ".join(
            f"{label(r['renderer'], r['sampler'])} {r['time_s'] * 1e3:8.1f} ms {r['noise_share'] * 100:6.2f} % "
            f"(bias {r['mean_bias'] * 100:+.3f} %)" for r in cur))  # fmt: skip

    log(f"timing done: {load()}")
    write_csv(rows, tag)
    summary = report_criterion(rows, tag)
    plot_criterion(rows, summary, tag)
    return rows


def load() -> str:
    import os

    return "load average " + " ".join(f"{v:.2f}" for v in os.getloadavg()) + f" ({os.cpu_count()} cores)"


def time_now() -> float:
    import time

    return time.perf_counter()


def crit_curve(rows, renderer, sampler=None):
    sel = [r for r in rows if r["renderer"] == renderer and (sampler is None or r["sampler"] == sampler)]
    return sorted(((r["spp"], r["time_s"], r["noise_share"], r["mean_bias"]) for r in sel), key=lambda x: x[0])


def report_criterion(rows, tag):
    """The table and the equal-criterion ratios; returns [(target, t_hilcam, {sampler: t_mitsuba})]."""
    hc = crit_curve(rows, "hilcam")
    smps = mitsuba_samplers(rows)
    mcs = {smp: crit_curve(rows, "mitsuba", smp) for smp in smps}
    r0 = rows[0]
    log(
        f"\n{tag}  ({r0['seeds']} seeds per point; share of the {r0['lit']} lit pixels whose σ over seeds > "
        f"{K} σ_cam; time: median render time per frame; bias: Σ mean / Σ reference − 1 over lit pixels; the "
        f"reference's halves differ by {float(r0['ref_halves_diff']) * 100:+.3f} %)"
    )
    log("| spp | hilcam ms | share % | bias % |" + "".join(f" M[{smp}] ms | share % | bias % |" for smp in smps))
    log("|" + "---:|" * (4 + 3 * len(smps)))
    for spp, ht, hs, hb in hc:
        cells = f"| {spp} | {ht * 1e3:.1f} | {hs * 100:.2f} | {hb * 100:+.3f} |"
        for smp in smps:
            m = {c[0]: c for c in mcs[smp]}.get(spp)
            cells += f" {m[1] * 1e3:.1f} | {m[2] * 100:.2f} | {m[3] * 100:+.3f} |" if m else " | | |"
        log(cells)
    hp = [(t, s) for _, t, s, _ in hc]
    four = next((s for spp, _, s, _ in hc if spp == 4), None)
    targets = ([("hilcam 4 spp", four)] if four else []) + [(f"{t * 100:.0f} %", t) for t in TARGETS]
    log(f"equal-criterion time ratio (Mitsuba time / hilcam time at the same share above {K} σ_cam; > 1: hilcam is faster):")
    summary = []
    for name, share in targets:
        th = interp_time(hp, share)
        tms = {smp: interp_time([(t, s) for _, t, s, _ in mcs[smp]], share) for smp in smps}
        cells = [f"M[{smp}] " + (f"{tm * 1e3:8.1f} ms, ratio {tm / th:5.2f}" if tm and th else "outside its range")
                 for smp, tm in tms.items()]  # fmt: skip
        best = min((tm for tm in tms.values() if tm), default=None)
        tail = f"; best Mitsuba ratio {best / th:.2f}" if best and th else ""
        hs = f"{th * 1e3:8.1f} ms" if th else "outside its range"
        log(f"  {name:>13} ({share * 100:5.2f} %): hilcam {hs}; " + "; ".join(cells) + tail)
        summary.append((name, share, th, tms))
    return summary


def plot_criterion(rows, summary, tag):
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    fig, ax = plt.subplots(figsize=(6.4, 4.8))
    lines = [("hilcam", None, "hilcam", "o-")] + [
        ("mitsuba", smp, f"Mitsuba 3 (llvm_ad_mono, {smp})", st)
        for smp, st in zip(mitsuba_samplers(rows), ("s-", "^-", "v-"))
    ]
    for name, smp, text, style in lines:
        c = crit_curve(rows, name, smp)
        ax.loglog([t for _, t, _, _ in c], [s * 100 for _, _, s, _ in c], style, label=text)
        for spp, t, s, _ in c:
            ax.annotate(str(spp), (t, s * 100), textcoords="offset points", xytext=(4, 4), fontsize=7)
    for name, share, _, _ in summary:
        ax.axhline(share * 100, color="grey", lw=0.6, ls=":")
    ax.set_xlabel("render time per frame (s)")
    ax.set_ylabel(f"lit pixels with σ over seeds > {K} σ_cam (%)")
    ax.set_title(tag, fontsize=9)
    ax.grid(True, which="both", alpha=0.3)
    ax.legend()
    fig.tight_layout()
    fig.savefig(OUT_DIR / f"{tag}.png", dpi=110)
    plt.close(fig)
    log(f"wrote {OUT_DIR / (tag + '.png')}")


def read_rows(path: Path) -> list[dict]:
    ints = ("width", "height", "depth", "spp", "seeds", "timed_frames", "lit", "above_noise")
    with path.open() as f:
        return [{k: (int(v) if k in ints else v if k in ("scene", "renderer", "sampler") else float(v)) for k, v in r.items()}
                for r in csv.DictReader(f)]  # fmt: skip


def is_criterion_csv(path: Path) -> bool:
    with path.open() as f:
        return "noise_share" in f.readline()


__all__ = ["ExportError", "bench_criterion", "check_criterion", "is_criterion_csv", "read_rows", "report_criterion"]
