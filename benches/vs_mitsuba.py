#!/usr/bin/env python3
"""hilcam vs Mitsuba 3, side by side: same scene, same conventions, error vs render time.

Usage (the wrapper scripts/bench-vs-mitsuba.sh builds hilcam in release first):
    python3 benches/vs_mitsuba.py scenes/sphere.toml --depth 4
    python3 benches/vs_mitsuba.py scenes/plate.toml --verify-only
    python3 benches/vs_mitsuba.py --quick            # 128×128, few spp, both scenes
    python3 benches/vs_mitsuba.py --criterion        # equal sensor criterion (vs_mitsuba_criterion.py)

What it does
1. Bootstraps itself: if Mitsuba is not importable, it creates target/mitsuba-venv, installs
   pinned mitsuba/drjit/numpy/matplotlib from PyPI, apt-get installs Debian's libllvm19 if no
   libLLVM ≥ 16 is found (drjit's LLVM backend miscompiles with LLVM 15), and re-executes
   itself inside the venv with DRJIT_LIBLLVM_PATH set. Mitsuba is a benchmark dependency
   only, never a runtime one.
2. Exports the hilcam scene to a Mitsuba 3 scene dict with the same conventions (see
   `mitsuba_scene`): box pixel filter, face normals, two-sided Lambert, directional sun of
   irradiance E, path tracer with max_depth = depth + 1 and hidden emitters, pinhole
   camera with the same field of view, principal point and image orientation. A material
   the MTL authors (no [materials] table) exports if it is Lambert; its `map_Kd` becomes
   a `bitmap` (bilinear, repeating) on the OBJ's `vt` (`mitsuba_bitmap`).
3. Verifies the conventions (mean radiance, image agreement, analytic plate radiance, and
   an asymmetric two-material scene with rotations and a principal-point offset) and
   exits non-zero if they disagree, before any timing.
4. Renders one converged reference (the average of a hilcam and a Mitsuba render at
   --ref-spp each, seeds distinct from the timed runs; the same reference for both
   curves), then times both renderers alternately over the spp list (median of --reps).

Error metric: relative RMSE = sqrt(mean over target pixels of (img − ref)²) / mean over
target pixels of ref, where target pixels are those where the reference is > 0 (the lit
target; background pixels are exactly 0 in both renderers and are excluded so the
number does not depend on how much empty sky the frame has).

Times are render-only and warm for both: hilcam's own printed render time of a frame
rendered after an untimed one through the same buffers (`--warm-up 1`, as every frame of
a running server; excludes scene load, BVH build and file write; taken as rays / (Mrays/s)
for sub-millisecond resolution); Mitsuba's `mi.render` + the numpy copy that syncs it,
after a warm-up render at the same spp so the JIT compile (and kernel-cache lookup) is
excluded.
"""

from __future__ import annotations

import argparse
import csv
import itertools
import math
import os
import re
import shutil
import statistics
import subprocess
import sys
import tempfile
import time
import tomllib
from dataclasses import dataclass, field
from pathlib import Path

ROOT = Path(__file__).resolve().parent.parent
VENV = ROOT / "target" / "mitsuba-venv"
OUT_DIR = ROOT / "target" / "vs-mitsuba"
PINNED = ["mitsuba==3.9.1", "drjit==1.5.0", "numpy>=1.26", "matplotlib>=3.8"]
LLVM_CANDIDATES = [
    "/usr/lib/x86_64-linux-gnu/libLLVM-19.so",
    "/usr/lib/x86_64-linux-gnu/libLLVM.so.19.1",
    "/usr/lib/x86_64-linux-gnu/libLLVM-18.so",
    "/usr/lib/x86_64-linux-gnu/libLLVM-17.so",
    "/usr/lib/x86_64-linux-gnu/libLLVM-16.so",
]


# ---------------------------------------------------------------------------------------
# 1. Bootstrap: venv + Mitsuba + libLLVM, then re-exec inside the venv.
# ---------------------------------------------------------------------------------------


def log(msg: str) -> None:
    print(msg, flush=True)


def find_llvm() -> str | None:
    env = os.environ.get("DRJIT_LIBLLVM_PATH")
    if env and Path(env).exists():
        return env
    return next((p for p in LLVM_CANDIDATES if Path(p).exists()), None)


def ensure_llvm() -> str | None:
    path = find_llvm()
    if path:
        return path
    if shutil.which("apt-get") and os.geteuid() == 0:
        log("vs_mitsuba: no libLLVM >= 16 found; apt-get install libllvm19 (benchmark only)")
        env = dict(os.environ, DEBIAN_FRONTEND="noninteractive")
        r = subprocess.run(["apt-get", "install", "-y", "-qq", "libllvm19"], env=env, check=False)
        if r.returncode != 0:
            subprocess.run(["apt-get", "update", "-qq"], env=env, check=False)
            subprocess.run(["apt-get", "install", "-y", "-qq", "libllvm19"], env=env, check=False)
    return find_llvm()


def bootstrap() -> None:
    """Make sure we run inside target/mitsuba-venv with Mitsuba and a usable libLLVM."""
    in_venv = Path(sys.prefix).resolve() == VENV.resolve()
    llvm = ensure_llvm()
    if in_venv:
        if llvm and os.environ.get("DRJIT_LIBLLVM_PATH") != llvm:
            os.environ["DRJIT_LIBLLVM_PATH"] = llvm
            os.execv(sys.executable, [sys.executable, *sys.argv])
        return
    py = VENV / "bin" / "python"
    if not py.exists():
        log(f"vs_mitsuba: creating {VENV}")
        subprocess.run([sys.executable, "-m", "venv", str(VENV)], check=True)
    probe = subprocess.run(
        [str(py), "-c", "import mitsuba, drjit, numpy, matplotlib"],
        capture_output=True,
        check=False,
    )
    if probe.returncode != 0:
        log(f"vs_mitsuba: pip install {' '.join(PINNED)} into {VENV}")
        subprocess.run(
            [str(py), "-m", "pip", "install", "-q", "--disable-pip-version-check", *PINNED],
            check=True,
        )
    env = dict(os.environ)
    if llvm:
        env["DRJIT_LIBLLVM_PATH"] = llvm
    os.execve(str(py), [str(py), str(Path(__file__).resolve()), *sys.argv[1:]], env)


# ---------------------------------------------------------------------------------------
# 2. The hilcam scene, read the way src/scene/file.rs reads it.
# ---------------------------------------------------------------------------------------


class ExportError(Exception):
    pass


@dataclass
class Camera:
    width: int
    height: int
    pitch_um: float
    focal_mm: float
    pp: tuple[float, float] = (0.0, 0.0)

    def focal_px(self) -> float:
        return self.focal_mm * 1e3 / self.pitch_um

    def scaled(self, width: int | None, height: int | None) -> Camera:
        """Same field of view at another resolution (src/cli/render.rs `scaled_camera`)."""
        if width is None and height is None:
            return self
        w = width if width is not None else round(height * self.width / self.height)
        k = self.width / w
        h = height if height is not None else max(1, round(self.height / k))
        return Camera(max(1, w), h, self.pitch_um * k, self.focal_mm, (self.pp[0] / k, self.pp[1] / k))


@dataclass
class MeshPart:
    """Triangles of one OBJ that use one scene material, with the entry's transform."""

    positions: list  # [(x, y, z)] in the OBJ's own coordinates
    faces: list  # [(i, j, k)] 0-based
    material: str
    to_world: list[list[float]]  # 4×4, OBJ → body frame
    uvs: list = field(default_factory=list)  # [(u, v)] the OBJ's `vt`
    uv_faces: list | None = None  # [(i, j, k)] into uvs, per face; None: no texture coordinates


@dataclass
class HilcamScene:
    path: Path
    parts: list[MeshPart]
    materials: dict[str, float | dict]  # name → Lambert ρ, a GGX material or a texture (export_material, mtl_material)
    lambertized: dict[str, str] = field(default_factory=dict)
    distortion: dict = field(default_factory=dict)  # the camera's non-zero Brown–Conrady terms (dropped)
    sun_irradiance: float = 593.1
    background: float = 0.0
    camera: Camera | None = None
    position: tuple = (0.0, 0.0, 10.0)
    attitude: tuple = (1.0, 0.0, 0.0, 0.0)
    sun: tuple = (0.0, 0.0, -1.0)
    spp: int = 4
    depth: int = 2
    raw_meshes: list = field(default_factory=list)

    def lambert_toml(self) -> str:
        """This scene as a hilcam scene file with every material a Lambert of the exported ρ
        (what hilcam must render when --lambertize changed materials; absolute paths)."""

        def v(x):
            if isinstance(x, str):
                return '"' + x.replace("\\", "\\\\").replace('"', '\\"') + '"'
            if isinstance(x, (list, tuple)):
                return "[" + ", ".join(v(y) for y in x) + "]"
            return repr(float(x)) if isinstance(x, float) else str(x)

        c = self.camera
        out = []
        for e in self.raw_meshes:
            out.append("[[mesh]]")
            out += [f"{k} = {v(x)}" for k, x in e.items()]
        for name, m in self.materials.items():
            if isinstance(m, dict) and "texture" in m:
                continue  # authored in the MTL, which the rewritten scene's absolute `obj` still finds
            out.append(f"[materials.{v(name)}]")
            if isinstance(m, dict):
                out += [f"{k} = {v(x)}" for k, x in m["hilcam"].items()]
            else:
                out += ['model = "lambert"', f"rho = {m!r}"]
        out += ["[sun]", f"irradiance = {self.sun_irradiance!r}", "[background]", f"radiance = {self.background!r}"]
        out += ["[camera]", f"width = {c.width}", f"height = {c.height}", f"pitch_um = {c.pitch_um!r}",
                f"focal_mm = {c.focal_mm!r}", f"principal_point_px = {v(list(c.pp))}"]  # fmt: skip
        out += [
            "[pose]",
            f"position = {v(list(self.position))}",
            f"attitude = {v(list(self.attitude))}",
            f"sun = {v(list(self.sun))}",
        ]
        out += ["[render]", f"spp = {self.spp}", f"depth = {self.depth}"]
        return "\n".join(out) + "\n"


def quat_to_mat(q):
    w, x, y, z = q
    n = math.sqrt(w * w + x * x + y * y + z * z)
    w, x, y, z = w / n, x / n, y / n, z / n
    return [
        [1 - 2 * (y * y + z * z), 2 * (x * y - w * z), 2 * (x * z + w * y)],
        [2 * (x * y + w * z), 1 - 2 * (x * x + z * z), 2 * (y * z - w * x)],
        [2 * (x * z - w * y), 2 * (y * z + w * x), 1 - 2 * (x * x + y * y)],
    ]


def matmul(a, b):
    return [[sum(a[i][k] * b[k][j] for k in range(len(b))) for j in range(len(b[0]))] for i in range(len(a))]


def transpose(a):
    return [list(r) for r in zip(*a)]


def matvec(a, v):
    return [sum(a[i][k] * v[k] for k in range(3)) for i in range(3)]


def euler_xyz_fixed(deg):
    """rotate_deg = [rx, ry, rz]: about X, then Y, then Z (fixed axes) → Rz·Ry·Rx."""
    rx, ry, rz = (math.radians(d) for d in deg)
    cx, sx, cy, sy, cz, sz = math.cos(rx), math.sin(rx), math.cos(ry), math.sin(ry), math.cos(rz), math.sin(rz)
    Rx = [[1, 0, 0], [0, cx, -sx], [0, sx, cx]]
    Ry = [[cy, 0, sy], [0, 1, 0], [-sy, 0, cy]]
    Rz = [[cz, -sz, 0], [sz, cz, 0], [0, 0, 1]]
    return matmul(Rz, matmul(Ry, Rx))


def read_mtl(path: Path) -> dict[str, dict[str, list[str]]] | None:
    """Each `newmtl` block of an MTL as {key: words after it} (the last occurrence wins)."""
    try:
        text = path.read_text()
    except OSError:
        return None
    mats, cur = {}, None
    for ln in text.splitlines():
        t = ln.split()
        if not t or t[0].startswith("#"):
            continue
        if t[0] == "newmtl":
            # "" (no MTL key) holds the MTL's folder, which `map_Kd` is relative to.
            cur = mats.setdefault(ln.split(None, 1)[1].strip(), {"": [str(path.parent)]})
        elif cur is not None:
            cur[t[0]] = t[1:]
    return mats


@dataclass
class ObjFile:
    positions: list
    uvs: list
    groups: dict  # material name → [((i, j, k), (ti, tj, tk) | None)]
    mtl: dict  # material name → its MTL block (read_mtl)


def read_obj(path: Path) -> ObjFile:
    """Positions, `vt` and fan-triangulated faces (with their `vt` indices) grouped by MTL
    material name (tobj's rules: a `usemtl` name missing from the material library, or no
    `usemtl`, is `default`)."""
    positions, uvs, groups = [], [], {}
    current = "default"
    mtl: dict = {}
    for ln in path.read_text().splitlines():
        t = ln.split()
        if not t:
            continue
        if t[0] == "v":
            positions.append(tuple(float(x) for x in t[1:4]))
        elif t[0] == "vt":
            uvs.append((float(t[1]), float(t[2]) if len(t) > 2 else 0.0))
        elif t[0] == "mtllib":
            mtl = read_mtl(path.parent / ln.split(None, 1)[1].strip()) or {}
        elif t[0] == "usemtl":
            name = ln.split(None, 1)[1].strip()
            current = name if name in mtl else "default"
        elif t[0] == "f":
            idx, tex = [], []
            for c in t[1:]:
                w = c.split("/")
                i = int(w[0])
                idx.append(i - 1 if i > 0 else len(positions) + i)
                j = int(w[1]) if len(w) > 1 and w[1] else None
                tex.append(None if j is None else j - 1 if j > 0 else len(uvs) + j)
            uv = None if None in tex else tex
            for k in range(1, len(idx) - 1):
                tri_uv = (uv[0], uv[k], uv[k + 1]) if uv else None
                groups.setdefault(current, []).append(((idx[0], idx[k], idx[k + 1]), tri_uv))
    if not groups:
        raise ExportError(f"{path}: no triangles")
    return ObjFile(positions, uvs, groups, mtl)


# Material presets (src/bsdf/spec.rs `BsdfSpec::build`): the fields a preset supplies when
# the scene file does not give them. Only the scalar diffuse ones matter here.
PRESETS = {
    ("lambert", "white_paint"): {"rho": 0.522},
    ("lambert", "gold_polyimide"): {"rho": 0.3717},
    ("blinn_phong", "gold_polyimide"): {"rho_d": 0.3717},
    ("improved_blinn_phong", "gold_polyimide"): {"rho_d": 0.3717},
    ("cook_torrance", "gold_polyimide"): {"rho_d": 0.3717},
}


# hilcam's conductor presets (render/bsdf/fresnel.rs `Metal::nk`): (n, k) over its band.
METALS = {"Au": (0.3804, 2.4792), "Al": (1.2337, 7.2602), "Ag": (0.1283, 3.4801), "Cu": (0.5479, 2.8396)}


def ggx_conductor(name: str, spec: dict) -> dict:
    """A `ggx_conductor` as both renderers' material: Mitsuba's `roughconductor` (GGX,
    visible-normal sampling, separable Smith G: the form docs/brdf.md states hilcam uses)
    with α = roughness² and the same complex index."""
    if "metal" in spec:
        if spec["metal"] not in METALS:
            raise ExportError(f"material `{name}`: metal `{spec['metal']}` unknown to the exporter")
        n, k = METALS[spec["metal"]]
    elif "n" in spec and "k" in spec:
        n, k = float(spec["n"]), float(spec["k"])
    else:
        raise ExportError(f"material `{name}` (ggx_conductor): only `metal` or `n` + `k` export (an `f0` has no Mitsuba twin)")
    r = float(spec["roughness"])
    return {
        "hilcam": {"model": "ggx_conductor", "roughness": r, "n": n, "k": k},
        "mitsuba": {"type": "roughconductor", "distribution": "ggx", "alpha": r * r, "eta": n, "k": k},
    }


def ggx_plastic(name: str, spec: dict) -> dict:
    """A `ggx_plastic` with `coupling = "mitsuba"` as Mitsuba's `roughplastic` (GGX,
    visible normals, `nonlinear = false`, α = roughness², int_ior = ior, ext_ior = 1).
    hilcam's default coupling returns all the light a white base receives and Mitsuba's
    does not (docs/brdf.md, "Plastic"): exporting it would compare two different models."""
    if spec.get("coupling", "energy") != "mitsuba":
        raise ExportError(
            f"material `{name}` (ggx_plastic): only `coupling = \"mitsuba\"` matches Mitsuba's roughplastic "
            f"(the default energy coupling differs by design, docs/brdf.md)"
        )
    r, rho, ior = float(spec["roughness"]), float(spec["rho"]), float(spec.get("ior", 1.5))
    return {
        "hilcam": {"model": "ggx_plastic", "roughness": r, "rho": rho, "ior": ior, "coupling": "mitsuba"},
        "mitsuba": {
            "type": "roughplastic",
            "distribution": "ggx",
            "alpha": r * r,
            "int_ior": ior,
            "ext_ior": 1.0,
            "nonlinear": False,
            "diffuse_reflectance": {"type": "rgb", "value": [rho, rho, rho]},
        },
    }


def export_material(name: str, spec: dict, lambertize: bool, overrides: dict[str, float]):
    """A material both renderers render alike: a Lambert ρ, or a GGX conductor's dict; any
    other model only with --lambertize (→ a Lambert of its stated albedo)."""
    model = spec.get("model")
    if model == "ggx_conductor":
        return ggx_conductor(name, spec), None
    if model == "ggx_plastic":
        return ggx_plastic(name, spec), None
    if "preset" in spec:
        if (model, spec["preset"]) not in PRESETS:
            raise ExportError(f"material `{name}`: preset `{spec['preset']}` of model `{model}` unknown to the exporter")
        spec = {**PRESETS[(model, spec["preset"])], **spec}
    if model == "lambert":
        return float(spec["rho"]), None
    if not lambertize:
        raise ExportError(
            f"material `{name}` has model `{model}`, which Mitsuba's `diffuse` cannot match; "
            f"rerun with --lambertize to replace it by a Lambert (ρ from --albedo {name}=V, "
            f"else its diffuse albedo field), knowing the comparison is then of a different scene"
        )
    if name in overrides:
        rho, why = overrides[name], "--albedo"
    else:
        key = next((k for k in ("rho", "rho_d", "kd", "albedo", "diffuse") if k in spec), None)
        if key is None or not isinstance(spec[key], (int, float)):
            raise ExportError(f"material `{name}` ({model}): no scalar diffuse albedo field; give --albedo {name}=V")
        rho, why = float(spec[key]), f"its `{key}`"
    return rho, f"{model} → Lambert ρ = {rho:g} ({why})"


def mtl_material(name: str, block: dict[str, list[str]], obj: Path):
    """A material the MTL authors (no [materials.NAME] table; src/scene/mtl_bsdf.rs): a
    Lambert of `Kd`'s band (the mean of r g b, default 1), or with `map_Kd` a texture
    times `Kd` (docs/scene.md, "Textures"). A GGX one (`Pr`, `Pm`, or a non-black `Ks`)
    takes hilcam's energy coupling, which Mitsuba's roughplastic does not match."""

    def rgb(key, default):
        w = block.get(key)
        if not w:
            return default
        v = [float(x) for x in w[:3]]
        return tuple(v * 3 if len(v) == 1 else v)

    if "Pr" in block or "Pm" in block or any(rgb("Ks", (0.0,))):
        raise ExportError(
            f"{obj}: MTL material `{name}` is GGX with hilcam's energy coupling, which Mitsuba's roughplastic "
            f"does not match; give a [materials.{name}] table (a table replaces the material's texture too)"
        )
    kd = rgb("Kd", (1.0, 1.0, 1.0))
    if "map_Kd" not in block:
        return sum(kd) / 3
    # hilcam: the last word is the file (options before it are ignored), beside the MTL.
    return {"texture": Path(block[""][0]) / block["map_Kd"][-1], "factor": kd}


def load_scene(path: Path, lambertize: bool = False, overrides: dict[str, float] | None = None) -> HilcamScene:
    src = tomllib.loads(path.read_text())
    base = path.parent
    overrides = overrides or {}
    mats, lamb = {}, {}
    for name, spec in src.get("materials", {}).items():
        rho, note = export_material(name, spec, lambertize, overrides)
        mats[name] = rho
        if note:
            lamb[name] = note
    if src.get("camera") is not None:
        c, file_sensor = src["camera"], {}
    else:
        cf = tomllib.loads((base / src["camera_file"]).read_text())
        c, file_sensor = cf["camera"], cf.get("sensor", {})
    cam = Camera(c["width"], c["height"], c["pitch_um"], c["focal_mm"], tuple(c.get("principal_point_px", (0.0, 0.0))))
    # `hilcam render` applies [sensor.optics] distortion (the scene's [sensor], else the camera
    # file's) to the rendered rays even without --sensor (src/pipeline.rs `radiance`).
    sensor = src.get("sensor", file_sensor)
    distortion = {k: v for k, v in (sensor.get("optics", {}).get("distortion") or {}).items() if v != 0}
    parts, raw = [], []
    for k, e in enumerate(src.get("mesh", [])):
        raw.append(dict(e, obj=str((base / e["obj"]).resolve())))
        obj = base / e["obj"]
        of = read_obj(obj)
        s = float(e.get("scale", 1.0))
        R = euler_xyz_fixed(e.get("rotate_deg", [0.0, 0.0, 0.0]))
        t = e.get("translate", [0.0, 0.0, 0.0])
        M = [[R[i][j] * s for j in range(3)] + [t[i]] for i in range(3)] + [[0.0, 0.0, 0.0, 1.0]]
        for mname, faces in of.groups.items():
            target = e.get("material", mname)
            if target not in mats:
                # The table wins; else the OBJ's own MTL (the first file to define a name
                # defines it for the scene, as hilcam does).
                if target != mname or mname not in of.mtl:
                    raise ExportError(f"{path}: mesh[{k}] ({obj}): material `{target}` has no [materials.{target}] entry")
                mats[target] = mtl_material(target, of.mtl[mname], obj)
            tris = [f for f, _ in faces]
            uv_faces = [u for _, u in faces]
            if isinstance(mats[target], dict) and "texture" in mats[target]:
                if None in uv_faces:
                    raise ExportError(f"{obj}: material `{target}` is textured but some of its faces have no `vt`")
                parts.append(MeshPart(of.positions, tris, target, M, of.uvs, uv_faces))
            else:
                parts.append(MeshPart(of.positions, tris, target, M))
    pose = src.get("pose", {})
    rend = src.get("render", {})
    return HilcamScene(
        path=path,
        parts=parts,
        materials=mats,
        lambertized=lamb,
        distortion=distortion,
        sun_irradiance=float(src.get("sun", {}).get("irradiance", 593.1)),
        background=float(src.get("background", {}).get("radiance", 0.0)),
        camera=cam,
        position=tuple(pose.get("position", (0.0, 0.0, 10.0))),
        attitude=tuple(pose.get("attitude", (1.0, 0.0, 0.0, 0.0))),
        sun=tuple(pose.get("sun", (0.0, 0.0, -1.0))),
        spp=int(rend.get("spp", 4)),
        depth=int(rend.get("depth", 2)),
        raw_meshes=raw,
    )


# ---------------------------------------------------------------------------------------
# 3. Export to Mitsuba 3.
# ---------------------------------------------------------------------------------------


def camera_axes_body(sc: HilcamScene):
    """Camera centre and camera-frame axes X, Y, Z expressed in the body (world) frame."""
    R = quat_to_mat(sc.attitude)  # body → camera
    Rt = transpose(R)
    centre = [-v for v in matvec(Rt, sc.position)]  # x_c = R x_b + p = 0
    axes = [matvec(Rt, e) for e in ([1, 0, 0], [0, 1, 0], [0, 0, 1])]
    return centre, axes


def write_part_obj(part: MeshPart, path: Path) -> None:
    used = sorted({i for f in part.faces for i in f})
    remap = {old: new for new, old in enumerate(used)}
    with path.open("w") as f:
        for i in used:
            x, y, z = part.positions[i]
            f.write(f"v {x!r} {y!r} {z!r}\n")
        if part.uv_faces is None:
            for a, b, c in part.faces:
                f.write(f"f {remap[a] + 1} {remap[b] + 1} {remap[c] + 1}\n")
            return
        used_uv = sorted({i for f in part.uv_faces for i in f})
        remap_uv = {old: new for new, old in enumerate(used_uv)}
        for i in used_uv:
            u, v = part.uvs[i]
            f.write(f"vt {u!r} {v!r}\n")
        for tri, uv in zip(part.faces, part.uv_faces):
            f.write("f " + " ".join(f"{remap[a] + 1}/{remap_uv[t] + 1}" for a, t in zip(tri, uv)) + "\n")


def mitsuba_scene(
    mi, sc: HilcamScene, cam: Camera, depth: int, sampler: str, spp: int, mesh_dir: Path, roulette: bool = False
) -> dict:
    """The Mitsuba 3 scene dict that renders what `hilcam render` renders.

    Image orientation: hilcam's camera frame has +X toward increasing column and +Y toward
    increasing row; Mitsuba's perspective sensor looks down its local +Z with local +X
    toward *decreasing* column (its look_at puts `left` there) and +Y toward decreasing
    row. So Mitsuba's local frame is hilcam's turned 180° about the boresight:
    to_world = look_at(origin = centre, target = centre + Z_cam, up = −Y_cam), which makes
    local X = up × dir = −X_cam. The asymmetric verification scene checks this.
    """
    if sc.background != 0.0:
        raise ExportError(
            f"{sc.path}: [background] radiance = {sc.background}: hilcam's background is seen only by "
            "escaping rays (no light sampling); the benchmark only exports black backgrounds"
        )
    centre, (_, Y, Z) = camera_axes_body(sc)
    T = mi.ScalarTransform4f
    to_world = T().look_at(
        origin=centre,
        target=[centre[i] + Z[i] for i in range(3)],
        up=[-Y[i] for i in range(3)],
    )
    sun_body = matvec(transpose(quat_to_mat(sc.attitude)), sc.sun)  # Rᵀ s
    n = math.sqrt(sum(v * v for v in sun_body))
    fov = math.degrees(2.0 * math.atan(cam.width * cam.pitch_um * 1e-6 / 2.0 / (cam.focal_mm * 1e-3)))
    # Bounds of the target for the clip planes (hilcam has none; keep them out of the way).
    pts = []
    for p in sc.parts:
        M = p.to_world
        for f in p.faces[:: max(1, len(p.faces) // 2000)]:
            for i in f:
                v = p.positions[i]
                pts.append([sum(M[r][c] * v[c] for c in range(3)) + M[r][3] for r in range(3)])
    dists = [math.dist(q, centre) for q in pts]
    far = 4.0 * max(dists) + 1.0
    near = max(1e-4, 0.25 * min(dists))
    sensor = {
        "type": "perspective",
        "fov_axis": "x",
        "fov": fov,
        "near_clip": near,
        "far_clip": far,
        "to_world": to_world,
        "sampler": {"type": sampler, "sample_count": spp},
        "film": {
            "type": "hdrfilm",
            "width": cam.width,
            "height": cam.height,
            "pixel_format": "luminance",
            "component_format": "float32",
            "rfilter": {"type": "box"},
        },
    }
    if cam.pp != (0.0, 0.0):
        # Fractions of the film size; Mitsuba's offset moves the image the opposite way to
        # hilcam's principal_point_px (measured by the asymmetric check), hence the minus.
        sensor["principal_point_offset_x"] = -cam.pp[0] / cam.width
        sensor["principal_point_offset_y"] = -cam.pp[1] / cam.height
    d = {
        "type": "scene",
        # Without --roulette hilcam runs with --no-roulette and Mitsuba's is off too (rr_depth
        # past max_depth). With it, both play roulette on the path continuation sampled at the
        # second surface interaction and later (hilcam: bounce ≥ 1, survival min(β, 1);
        # Mitsuba: depth ≥ rr_depth = 2 counted after the interaction, survival min(β, 0.95)).
        "integrator": {
            "type": "path",
            "max_depth": depth + 1,
            "rr_depth": 2 if roulette else depth + 2,
            "hide_emitters": True,
        },
        "sensor": sensor,
        "sun": {
            "type": "directional",
            "direction": [-v / n for v in sun_body],
            "irradiance": {"type": "spectrum", "value": sc.sun_irradiance},
        },
    }
    mesh_dir.mkdir(parents=True, exist_ok=True)
    for k, p in enumerate(sc.parts):
        f = mesh_dir / f"{sc.path.stem}_{k}_{p.material}.obj"
        write_part_obj(p, f)
        d[f"mesh_{k}"] = {
            "type": "obj",
            "filename": str(f),
            "face_normals": True,
            # Mitsuba stores an OBJ `vt` (u, v) as (u, 1 − v) and its bitmap's v = 0 is the
            # image's top row (both measured), so OBJ v = 0 is the bottom row, as in hilcam.
            "flip_tex_coords": True,
            "to_world": T(p.to_world),
            "bsdf": {
                "type": "twosided",
                "material": mitsuba_material(mi, sc.materials[p.material]),
            },
        }
    return d


# ---------------------------------------------------------------------------------------
# Renderers.
# ---------------------------------------------------------------------------------------


def mitsuba_material(mi, m: float | dict) -> dict:
    """Mitsuba's twin of an exported material (see export_material, mtl_material)."""
    if isinstance(m, dict) and "texture" in m:
        return {"type": "diffuse", "reflectance": mitsuba_bitmap(mi, m["texture"], m["factor"])}
    if isinstance(m, dict):
        return m["mitsuba"]
    return {"type": "diffuse", "reflectance": {"type": "spectrum", "value": m}}


def mitsuba_bitmap(mi, path: Path, factor: tuple) -> dict:
    """hilcam's band texture as Mitsuba's `bitmap` (bilinear, repeating, no mip-map: what
    hilcam's prefiltered frame converges to, docs/brdf.md "Textures"). A one-channel image
    under `Kd 1` is handed over as the file, Mitsuba sRGB-decoding it itself (raw = false);
    any other is decoded by Mitsuba, multiplied by Kd and reduced to the mean of r g b as
    hilcam does (Mitsuba's mono variant would take the luminance), then passed linear."""
    import numpy as np

    tex = {"type": "bitmap", "filter_type": "bilinear", "wrap_mode": "repeat"}
    if not path.exists():
        raise ExportError(f"texture {path} cannot be read")
    bmp = mi.Bitmap(str(path))
    if bmp.pixel_format() == mi.Bitmap.PixelFormat.Y and tuple(factor) == (1.0, 1.0, 1.0):
        return dict(tex, filename=str(path), raw=False)
    rgb = np.array(bmp.convert(mi.Bitmap.PixelFormat.RGB, mi.Struct.Type.Float32, srgb_gamma=False))
    band = (rgb * np.asarray(factor, dtype=np.float32)).mean(axis=2, keepdims=True)
    return dict(tex, bitmap=mi.Bitmap(np.ascontiguousarray(band, dtype=np.float32)), raw=True)


def read_pfm(path: Path):
    import numpy as np

    with path.open("rb") as f:
        kind = f.readline().strip()
        if kind != b"Pf":
            raise ExportError(f"{path}: not a greyscale PFM ({kind!r})")
        w, h = (int(v) for v in f.readline().split())
        scale = float(f.readline())
        data = np.frombuffer(f.read(), dtype="<f4" if scale < 0 else ">f4", count=w * h)
    return np.flipud(data.reshape(h, w)).astype(np.float64)  # PFM rows are bottom-to-top


SUMMARY = re.compile(r": ([0-9.]+) s, (\d+) rays \(([0-9.]+) Mrays/s\)")


class Hilcam:
    def __init__(
        self,
        exe: Path,
        scene_file: Path,
        cam: Camera,
        depth: int,
        sampler: str,
        sequence: str,
        tmp: Path,
        roulette=False,
        adaptive=True,
    ):
        self.exe, self.scene_file, self.cam, self.depth, self.tmp = exe, scene_file, cam, depth, tmp
        self.sampler, self.sequence, self.roulette, self.adaptive = sampler, sequence, roulette, adaptive

    def render(self, spp: int, seed: int, scene_file: Path | None = None, warm: bool = False):
        """One frame; `warm`: after an untimed one through the same buffers (`--warm-up 1`),
        as Mitsuba is timed after its warm-up render and as a running server renders."""
        out = self.tmp / "hilcam.pfm"
        cmd = [
            str(self.exe), "render", str(scene_file or self.scene_file), "--out", str(out),
            "--spp", str(spp), "--depth", str(self.depth), "--sampler", self.sampler, "--sequence", self.sequence, "--seed", str(seed),
            "--width", str(self.cam.width), "--height", str(self.cam.height),
        ] + ([] if self.roulette else ["--no-roulette"]) + ([] if self.adaptive else ["--no-adaptive"])  # fmt: skip
        cmd += ["--warm-up", "1"] if warm else []
        r = subprocess.run(cmd, capture_output=True, text=True, check=False)
        if r.returncode != 0:
            raise RuntimeError(f"hilcam failed: {' '.join(cmd)}\n{r.stderr}")
        m = SUMMARY.search(r.stdout)
        if not m:
            raise RuntimeError(f"cannot parse hilcam's summary: {r.stdout!r}")
        secs, rays, mrays = float(m[1]), int(m[2]), float(m[3])
        # The printed seconds have 1 ms resolution; rays / rate has ~4 significant digits.
        t = rays / (mrays * 1e6) if mrays > 0 and rays > 0 else secs
        return read_pfm(out), t


class Mitsuba:
    def __init__(self, mi, np, scene_dict: dict):
        self.mi, self.np = mi, np
        self.scene = mi.load_dict(scene_dict)
        self.warm: set[int] = set()

    def render(self, spp: int, seed: int):
        mi, np = self.mi, self.np
        if spp not in self.warm:  # JIT compile (or kernel-cache load) outside the timing
            np.array(mi.render(self.scene, spp=spp, seed=10_000_000 + seed))
            self.warm.add(spp)
        t0 = time.perf_counter()
        img = np.array(mi.render(self.scene, spp=spp, seed=seed))
        t = time.perf_counter() - t0
        return img[..., 0].astype(np.float64), t

    def render_passes(self, spp: int, seed: int, pass_spp: int):
        """The mean of ceil(spp / pass_spp) renders with distinct seeds (a 1024² launch at
        thousands of spp would exceed drjit's 2³² wavefront limit and this machine's memory)."""
        n = max(1, math.ceil(spp / pass_spp))
        t0 = time.perf_counter()
        acc = None
        for k in range(n):
            s = min(pass_spp, spp - k * pass_spp)
            img = self.np.array(self.mi.render(self.scene, spp=s, seed=seed + 7919 * k))[..., 0].astype(self.np.float64)
            acc = img * s if acc is None else acc + img * s
        return acc / spp, time.perf_counter() - t0


def rel_rmse(img, ref) -> float:
    import numpy as np

    mask = ref > 0
    if not mask.any():
        raise ExportError("the reference image is black: nothing to compare")
    return float(np.sqrt(np.mean((img[mask] - ref[mask]) ** 2)) / np.mean(ref[mask]))


# ---------------------------------------------------------------------------------------
# Verification of the conventions.
# ---------------------------------------------------------------------------------------


def interior(img, margin: int = 2):
    """Pixels whose (2·margin+1)² neighbourhood is all non-zero (fully covered)."""
    import numpy as np

    m = img > 0
    out = m.copy()
    h, w = m.shape
    for dy in range(-margin, margin + 1):
        for dx in range(-margin, margin + 1):
            sh = np.zeros_like(m)
            sh[max(0, dy) : h + min(0, dy), max(0, dx) : w + min(0, dx)] = m[
                max(0, -dy) : h + min(0, -dy), max(0, -dx) : w + min(0, -dx)
            ]
            out &= sh
    return out


def make_asymmetric_scene(tmp: Path) -> Path:
    """An L of two boxes (long arm +X body, short arm +Y, different ρ), rotated, seen with a
    rolled attitude, an oblique sun and a principal-point offset: any flip, swap, sign or
    offset error in the export moves or mirrors it."""
    tmp.mkdir(parents=True, exist_ok=True)

    def box(name, lo, hi, mat):
        (x0, y0, z0), (x1, y1, z1) = lo, hi
        v = [(x, y, z) for x in (x0, x1) for y in (y0, y1) for z in (z0, z1)]
        quads = [(0, 1, 3, 2), (4, 6, 7, 5), (0, 4, 5, 1), (2, 3, 7, 6), (0, 2, 6, 4), (1, 5, 7, 3)]
        lines = [f"mtllib {name}.mtl", f"usemtl {mat}"] + [f"v {a} {b} {c}" for a, b, c in v]
        lines += ["f " + " ".join(str(i + 1) for i in q) for q in quads]
        (tmp / f"{name}.obj").write_text("\n".join(lines) + "\n")
        (tmp / f"{name}.mtl").write_text(f"newmtl {mat}\n")

    box("arm_x", (-0.5, -0.5, -0.3), (2.5, 0.5, 0.3), "light")
    box("arm_y", (-0.5, 0.5, -0.3), (0.5, 1.8, 0.3), "dark")
    s = 1 / math.sqrt(3)
    (tmp / "asym.toml").write_text(
        f"""
[[mesh]]
obj = "arm_x.obj"
rotate_deg = [20.0, -15.0, 10.0]
translate = [0.2, -0.1, 0.3]
scale = 1.1
[[mesh]]
obj = "arm_y.obj"
rotate_deg = [20.0, -15.0, 10.0]
translate = [0.2, -0.1, 0.3]
scale = 1.1
[materials.light]
model = "lambert"
rho = 0.8
[materials.dark]
model = "lambert"
rho = 0.3
[sun]
irradiance = 593.1
[camera]
width = 1024
height = 768
pitch_um = 5.5
focal_mm = 16.0
principal_point_px = [60.0, -40.0]
[pose]
position = [0.3, -0.2, 14.0]
attitude = [0.9659258262890683, 0.0, 0.0, 0.25881904510182]
sun = [{s}, {-s}, {-s}]
"""
    )
    return tmp / "asym.toml"


@dataclass
class Check:
    name: str
    value: float
    limit: float
    ok: bool = field(init=False)

    def __post_init__(self):
        self.ok = abs(self.value) <= self.limit


def verify(args, mi, np, scene_path: Path, sc: HilcamScene, depth: int, tmp: Path, exe: Path) -> list[Check]:
    """Both renderers at high spp on a small image: image and mean radiance must agree."""
    cam = sc.camera.scaled(args.verify_width, None)
    checks = []
    h = Hilcam(exe, scene_path, cam, depth, args.hilcam_sampler, args.hilcam_sequence, tmp, args.roulette, adaptive=False)
    m = Mitsuba(
        mi, np, mitsuba_scene(mi, sc, cam, depth, args.sampler[0], args.verify_spp, tmp / "meshes", args.roulette)
    )
    a, _ = h.render(args.verify_spp, seed=777)
    b, _ = m.render(args.verify_spp, seed=777)
    # A second seed of each: their differences measure each image's own noise, which is
    # taken out of the comparison in quadrature (E|a − b|² = bias² + σa² + σb²).
    a2, _ = h.render(args.verify_spp, seed=778)
    b2, _ = m.render(args.verify_spp, seed=778)
    tag = f"{scene_path.name} {cam.width}x{cam.height} depth {depth} @ {args.verify_spp} spp"
    lit = (a > 0) | (b > 0)
    raw, noise_a, noise_b = _rel_diff(a, b), _rel_diff(a, a2) / math.sqrt(2), _rel_diff(b, b2) / math.sqrt(2)
    corrected = math.sqrt(max(0.0, raw**2 - noise_a**2 - noise_b**2))
    log(
        f"{tag}: rel. RMSE raw {raw * 100:.3f} %, noise hilcam {noise_a * 100:.3f} %, "
        f"Mitsuba {noise_b * 100:.3f} %, noise-corrected {corrected * 100:.3f} %"
    )
    checks.append(Check(f"{tag}: rel. RMSE hilcam vs Mitsuba (noise-corrected)", corrected, args.verify_tol))
    mean_tol = args.verify_mean_tol if args.verify_mean_tol is not None else args.verify_tol / 2
    checks.append(Check(f"{tag}: mean radiance ratio − 1", float(a[lit].mean() / b[lit].mean() - 1), mean_tol))
    inner = interior(a) & interior(b)
    planar = _planar_normal(sc)
    rhos = {sc.materials[p.material] for p in sc.parts if not isinstance(sc.materials[p.material], dict)}
    if planar is not None and inner.any() and len(rhos) == 1:
        n = planar
        sun = matvec(transpose(quat_to_mat(sc.attitude)), sc.sun)
        cos = abs(sum(n[i] * sun[i] for i in range(3))) / math.sqrt(sum(v * v for v in sun))
        rho = next(iter(rhos))
        analytic = rho * sc.sun_irradiance * cos / math.pi
        for who, img in (("hilcam", a), ("Mitsuba", b)):
            checks.append(
                Check(
                    f"{tag}: {who} interior mean {img[inner].mean():.3f} vs analytic {analytic:.3f} (ratio − 1)",
                    float(img[inner].mean() / analytic - 1),
                    1e-3,
                )
            )
    return checks


def _rel_diff(a, b) -> float:
    """RMSE of the difference over pixels lit in either, over the mean of both."""
    import numpy as np

    lit = (a > 0) | (b > 0)
    return float(np.sqrt(np.mean((a[lit] - b[lit]) ** 2)) / (0.5 * (a[lit].mean() + b[lit].mean())))


def _planar_normal(sc: HilcamScene):
    """The common face normal (body frame) if every triangle lies in one orientation and one
    material is used, else None (the analytic check applies to plates only)."""
    normals = []
    for p in sc.parts:
        M = p.to_world
        for f in p.faces:
            v = [[sum(M[r][c] * p.positions[i][c] for c in range(3)) for r in range(3)] for i in f]
            e1 = [v[1][k] - v[0][k] for k in range(3)]
            e2 = [v[2][k] - v[0][k] for k in range(3)]
            n = [e1[1] * e2[2] - e1[2] * e2[1], e1[2] * e2[0] - e1[0] * e2[2], e1[0] * e2[1] - e1[1] * e2[0]]
            ln = math.sqrt(sum(x * x for x in n))
            if ln > 0:
                normals.append([x / ln for x in n])
            if len(normals) > 64:
                break
    if not normals or len({p.material for p in sc.parts}) != 1:
        return None
    n0 = normals[0]
    if all(abs(abs(sum(n0[k] * n[k] for k in range(3))) - 1) < 1e-6 for n in normals):
        return n0
    return None


# ---------------------------------------------------------------------------------------
# 4. Timing and the equal-error ratio.
# ---------------------------------------------------------------------------------------


# The brief's 20 %…2 % band, plus 3 % and 1 % where the curves start below 20 %.
EQUAL_ERRORS = (0.20, 0.10, 0.05, 0.03, 0.02, 0.01)


def interp_time(points: list[tuple[float, float]], err: float) -> float | None:
    """Time at which a (time, error) curve reaches `err`: log-log linear interpolation
    between the two measured points that bracket it; None outside the measured range."""
    pts = sorted(points, key=lambda p: p[0])
    for (t0, e0), (t1, e1) in itertools.pairwise(pts):
        lo, hi = min(e0, e1), max(e0, e1)
        if lo <= err <= hi and e0 != e1:
            u = (math.log(err) - math.log(e0)) / (math.log(e1) - math.log(e0))
            return math.exp(math.log(t0) + u * (math.log(t1) - math.log(t0)))
    return None


def make_renderers(args, mi, np, scene_path: Path, sc: HilcamScene, cam, depth: int, tmp: Path, exe: Path):
    """hilcam as tested, hilcam for the reference, and Mitsuba per --sampler, on `cam`."""
    h = Hilcam(exe, scene_path, cam, depth, args.hilcam_sampler, args.hilcam_sequence, tmp, args.roulette)
    # The reference's hilcam half samples every pixel alike (--no-adaptive): it must not
    # depend on the sampling under test (adaptive sampling is unbiased, but the reference
    # should not have to rely on that).
    h_uniform = Hilcam(
        exe, scene_path, cam, depth, args.hilcam_sampler, args.hilcam_sequence, tmp, args.roulette, adaptive=False
    )
    ms = {
        smp: Mitsuba(mi, np, mitsuba_scene(mi, sc, cam, depth, smp, 1, tmp / "meshes", args.roulette))
        for smp in args.sampler
    }
    return h, h_uniform, ms


def bench(args, mi, np, scene_path: Path, sc: HilcamScene, depth: int, tmp: Path, exe: Path) -> list[dict]:
    cam = sc.camera.scaled(args.width, args.height)
    rr = "_rr" if args.roulette else ""
    tag = f"{scene_path.stem}_{cam.width}x{cam.height}_d{depth}{rr}_{'+'.join(args.sampler)}"
    h, h_uniform, ms = make_renderers(args, mi, np, scene_path, sc, cam, depth, tmp, exe)

    log(
        f"\n== {scene_path.name}: {cam.width}x{cam.height}, depth {depth}, hilcam {args.hilcam_sequence} sequence + "
        f"{args.hilcam_sampler} bounces, Mitsuba sampler {', '.join(args.sampler)}, "
        f"Russian roulette {'on in both' if args.roulette else 'off in both'}"
    )
    t0 = time.perf_counter()
    ref_h, th = h_uniform.render(args.ref_spp, seed=1_000_003)
    ref_m, tm = ms[args.sampler[0]].render_passes(args.ref_spp, 1_000_003, args.ref_pass_spp)
    ref = 0.5 * (ref_h + ref_m)
    # The reference's own noise adds to every measured error: E|img − ref|² = err² + var(ref).
    # With independent halves, var(ref) ≈ |ref_h − ref_m|² / 4 (no bias between them, which
    # the checks established), so it is estimated and subtracted in quadrature.
    mask = ref > 0
    ref_noise = float(np.sqrt(np.mean((ref_h[mask] - ref_m[mask]) ** 2) / 4) / np.mean(ref[mask]))
    log(
        f"reference: mean of hilcam and Mitsuba ({args.sampler[0]}) at {args.ref_spp} spp each (hilcam {th:.2f} s, "
        f"Mitsuba {tm:.2f} s; they differ by rel. RMSE {_rel_diff(ref_h, ref_m) * 100:.2f} %, wall "
        f"{time.perf_counter() - t0:.0f} s); reference noise {ref_noise * 100:.3f} % (subtracted in quadrature)"
    )

    renderers = [("hilcam", args.hilcam_sequence, h)]
    if args.hilcam_uniform_too:
        renderers.append(("hilcam-uniform", args.hilcam_sequence, h_uniform))
    renderers += [("mitsuba", smp, m) for smp, m in ms.items()]
    rows = []
    # hilcam's own budgets (fractions: --hilcam-spp) join Mitsuba's in one alternation.
    for spp in sorted(set(args.spp) | set(args.hilcam_spp)):
        for rep in range(args.reps):
            seed = 1 + rep
            # Alternate renderers (order rotated every repetition) so machine load hits all.
            k = rep % len(renderers)
            for name, smp, r in renderers[k:] + renderers[:k]:
                if not timed(name, smp, spp) or (name != "hilcam" and spp not in args.spp):
                    continue
                img, t = r.render(spp, seed, warm=True) if isinstance(r, Hilcam) else r.render(spp, seed)
                raw = rel_rmse(img, ref)
                rows.append({"scene": scene_path.stem, "width": cam.width, "height": cam.height, "depth": depth,
                             "sampler": smp, "renderer": name, "spp": spp, "rep": rep, "time_s": t,
                             "rel_rmse_raw": raw, "rel_rmse": math.sqrt(max(0.0, raw**2 - ref_noise**2)),
                             "ref_noise": ref_noise})  # fmt: skip
        cur = [r for r in rows if r["spp"] == spp]
        times = "   ".join(
            f"{label(n, smp)} {statistics.median(r['time_s'] for r in cur if (r['renderer'], r['sampler']) == (n, smp)) * 1e3:9.2f} ms"
            for n, smp, _ in renderers
            if any((r["renderer"], r["sampler"]) == (n, smp) for r in cur)
        )
        log(f"  spp {spp:>4}: {times}")

    write_csv(rows, tag)
    summary = report(rows, tag)
    plot(rows, summary, tag)
    return rows


def write_csv(rows: list[dict], tag: str) -> None:
    """The rows as OUT_DIR/<tag>.csv (columns from the first row)."""
    OUT_DIR.mkdir(parents=True, exist_ok=True)
    with (OUT_DIR / f"{tag}.csv").open("w", newline="") as f:
        w = csv.DictWriter(f, fieldnames=list(rows[0]))
        w.writeheader()
        w.writerows(rows)
    log(f"wrote {OUT_DIR / (tag + '.csv')}")


def mitsuba_spp(sampler: str, spp: int) -> int:
    """The sample count Mitsuba really takes: `multijitter` rounds up to a near-square grid
    (resx = ⌊√spp⌋, resy = ⌈spp/resx⌉; 32 → 35, 128 → 132, with a warning) and is then also
    several times slower per sample (measured: 2.5× at 32 and 128), so such counts are skipped."""
    if sampler != "multijitter":
        return spp
    rx = max(1, math.isqrt(spp))
    return rx * -(-spp // rx)


def timed(renderer: str, sampler: str, spp) -> bool:
    """Whether this renderer's curve has a point at `spp` (Mitsuba: whole counts it really takes)."""
    if renderer.startswith("hilcam"):
        return True
    return float(spp).is_integer() and mitsuba_spp(sampler, int(spp)) == spp


def spp_number(text: str):
    """A budget as written: an int when whole (4), else a float (1.25)."""
    v = float(text)
    return int(v) if v.is_integer() else v


def label(renderer: str, sampler: str) -> str:
    return renderer if renderer.startswith("hilcam") else f"Mitsuba[{sampler}]"


def mitsuba_samplers(rows) -> list[str]:
    return list(dict.fromkeys(r["sampler"] for r in rows if r["renderer"] == "mitsuba"))


def curve(rows, renderer, sampler=None):
    out = []
    sel = [r for r in rows if r["renderer"] == renderer and (sampler is None or r["sampler"] == sampler)]
    sel = [r for r in sel if timed(r["renderer"], r["sampler"], r["spp"])]
    for spp in sorted({r["spp"] for r in sel}):
        cur = [r for r in sel if r["spp"] == spp]
        # Median time; error as the RMS over repetitions (its expectation is what matters).
        t = statistics.median(r["time_s"] for r in cur)
        e = math.sqrt(statistics.mean(r["rel_rmse"] ** 2 for r in cur))
        out.append((spp, t, e))
    return out


def report(rows, tag):
    """Print the table and the equal-error ratios; returns [(sampler, err, t_hilcam, t_mitsuba)]."""
    hc = curve(rows, "hilcam")
    smps = mitsuba_samplers(rows)
    mcs = {smp: curve(rows, "mitsuba", smp) for smp in smps}
    noise = {r.get("ref_noise") for r in rows if r.get("ref_noise") not in (None, "")}
    note = f"; reference noise {float(next(iter(noise))) * 100:.3f} % subtracted" if len(noise) == 1 else ""
    log(f"\n{tag}  (median of {max(r['rep'] for r in rows) + 1} alternate runs; error = rel. RMSE vs reference over lit pixels{note})")
    head = "| spp | hilcam ms | hilcam err % |" + "".join(
        f" M[{smp}] ms | M[{smp}] err % | ratio M/h |" for smp in smps
    )
    log(head)
    log("|" + "---:|" * (3 + 3 * len(smps)))
    by_spp = {spp: (t, e) for spp, t, e in hc}
    for spp, ht, he in hc:
        cells = f"| {spp} | {ht * 1e3:.1f} | {he * 100:.2f} |"
        for smp in smps:
            m = {s: (t, e) for s, t, e in mcs[smp]}.get(spp)
            cells += f" {m[0] * 1e3:.1f} | {m[1] * 100:.2f} | {m[0] / by_spp[spp][0]:.2f} |" if m else " | | |"
        log(cells)
    hp = [(t, e) for _, t, e in hc]
    summary = []
    for smp in smps:
        mp = [(t, e) for _, t, e in mcs[smp]]
        log(f"equal-error speed ratio vs Mitsuba[{smp}] (Mitsuba time / hilcam time; > 1 means hilcam is faster):")
        for err in EQUAL_ERRORS:
            th, tm = interp_time(hp, err), interp_time(mp, err)
            if th and tm:
                log(f"  at {err * 100:4.0f} % error: hilcam {th * 1e3:9.2f} ms, Mitsuba {tm * 1e3:9.2f} ms, ratio {tm / th:.2f}")
                summary.append((smp, err, th, tm))
            else:
                missing = " and ".join(n for n, v in (("hilcam", th), ("Mitsuba", tm)) if not v)
                log(f"  at {err * 100:4.0f} % error: outside the measured range of {missing}")
    uc = curve(rows, "hilcam-uniform")
    if uc:
        up = [(t, e) for _, t, e in uc]
        log("hilcam --no-adaptive (same alternation): " + ", ".join(f"{spp} spp {t * 1e3:.1f} ms {e * 100:.2f} %" for spp, t, e in uc))
        for err in EQUAL_ERRORS:
            tu, ta = interp_time(up, err), interp_time(hp, err)
            if tu and ta:
                log(f"  at {err * 100:4.0f} % error: adaptive {ta * 1e3:9.2f} ms, uniform {tu * 1e3:9.2f} ms, gain {tu / ta:.2f}")
            for smp in smps:
                tm = interp_time([(t, e) for _, t, e in mcs[smp]], err)
                if tu and tm:
                    log(f"      uniform vs Mitsuba[{smp}]: ratio {tm / tu:.2f}")
    for who, pts in [("hilcam", hp)] + [(f"Mitsuba[{smp}]", [(t, e) for _, t, e in mcs[smp]]) for smp in smps]:
        c = curve(rows, "hilcam") if who == "hilcam" else mcs[who[8:-1]]
        t10, s10 = interp_time(pts, 0.10), interp_time([(spp, e) for spp, _, e in c], 0.10)
        log(f"  {who} reaches 10 % at " + (f"{t10 * 1e3:.1f} ms ({1 / t10:.1f} frames/s), {s10:.1f} spp" if t10 else "(outside the measured range)"))
    return summary


def plot(rows, summary, tag):
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    fig, ax = plt.subplots(figsize=(6.4, 4.8))
    lines = [("hilcam", None, "hilcam", "o-")]
    if curve(rows, "hilcam-uniform"):
        lines.append(("hilcam-uniform", None, "hilcam --no-adaptive", "o--"))
    lines += [
        ("mitsuba", smp, f"Mitsuba 3 (llvm_ad_mono, {smp})", st)
        for smp, st in zip(mitsuba_samplers(rows), ("s-", "^-", "v-"))
    ]
    for name, smp, text, style in lines:
        c = curve(rows, name, smp)
        ax.loglog([t for _, t, _ in c], [e * 100 for _, _, e in c], style, label=text)
        for spp, t, e in c:
            ax.annotate(str(spp), (t, e * 100), textcoords="offset points", xytext=(4, 4), fontsize=7)
    ax.set_xlabel("render time per frame (s)")
    ax.set_ylabel("relative RMSE vs reference (%)")
    ax.set_title(tag)
    ax.grid(True, which="both", alpha=0.3)
    ax.legend()
    fig.tight_layout()
    fig.savefig(OUT_DIR / f"{tag}.png", dpi=110)
    plt.close(fig)
    log(f"wrote {OUT_DIR / (tag + '.png')}")


# ---------------------------------------------------------------------------------------


def hilcam_scene_file(path: Path, sc: HilcamScene, tmp: Path) -> Path:
    """The file hilcam renders: the scene itself, or a rewritten copy (all-Lambert, pinhole
    camera) if materials were lambertized or the camera has lens distortion, which Mitsuba's
    `perspective` sensor cannot model (the copy's [camera] has no distortion)."""
    if not sc.lambertized and not sc.distortion:
        return path
    for name, note in sc.lambertized.items():
        log(f"NOTE: --lambertize: material `{name}`: {note} (for both renderers)")
    if sc.distortion:
        log(f"NOTE: camera distortion {sc.distortion} dropped: both renderers render a pinhole camera")
    out = tmp / f"{path.stem}.toml"
    out.write_text(sc.lambert_toml())
    return out


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("scenes", nargs="*", type=Path, help="hilcam scene files (default: sphere and plate)")
    ap.add_argument("--depth", type=int, action="append", help="surface interactions (repeatable; default: the scene's)")
    ap.add_argument(
        "--spp",
        type=lambda s: [int(v) for v in s.split(",")],
        default=None,
        help="spp ladder (default 1,2,4,8,16,32,64; with --criterion 1,2,4,8,16,32,64,128,256; multijitter skips 32 and 128)",
    )
    ap.add_argument(
        "--hilcam-spp",
        type=lambda s: [spp_number(v) for v in s.split(",")],
        default=[],
        metavar="LIST",
        help="budgets only hilcam renders, in the same alternation (fractions too, e.g. 1.25,1.5: "
        "hilcam's curve gets points between Mitsuba's whole sample counts)",
    )
    ap.add_argument(
        "--reps",
        type=int,
        default=None,
        help="repetitions per spp (median time; default 3); with --criterion: the first seeds, timed for "
        "every renderer in the same rounds (default: all --seeds)",
    )
    ap.add_argument(
        "--criterion",
        action="store_true",
        help="equal sensor criterion (issue 36): per spp, --seeds seeds of one pose from each renderer through "
        "the scene camera's sensor chain (hilcam bench charge); the share of lit pixels whose σ over seeds "
        "exceeds 0.5 σ_cam, and the time ratio at equal share (default scene satellite_matte, 256 px, "
        "both Mitsuba samplers)",
    )
    ap.add_argument("--seeds", type=int, default=16, help="with --criterion: seeds per renderer and spp (>= 16 for the issue)")
    ap.add_argument("--ref-chunks", type=int, default=4, help="with --criterion: reference chunks of --ref-spp per renderer")
    ap.add_argument("--width", type=int, default=None, help="image width (default: the camera's)")
    ap.add_argument("--height", type=int, default=None)
    ap.add_argument("--ref-spp", type=int, default=1024, help="spp of each half of the reference")
    ap.add_argument("--ref-pass-spp", type=int, default=256, help="Mitsuba's reference is rendered in passes of this many spp")
    ap.add_argument(
        "--sampler",
        choices=["independent", "multijitter"],
        action="append",
        help="Mitsuba's sampler (repeatable: each is timed in the same alternation; default independent)",
    )
    ap.add_argument(
        "--hilcam-sequence",
        choices=["sobol", "independent"],
        default="sobol",
        help="hilcam's random-number sequence (default sobol, hilcam's own default)",
    )
    ap.add_argument(
        "--hilcam-sampler",
        choices=["cosine", "uniform", "brdf"],
        default="cosine",
        help="hilcam's bounce sampler (cosine = Mitsuba's diffuse BSDF sampling)",
    )
    ap.add_argument(
        "--hilcam-uniform-too",
        action="store_true",
        help="also time hilcam with --no-adaptive (every pixel the same spp) in the same alternation",
    )
    ap.add_argument(
        "--roulette",
        action="store_true",
        help="Russian roulette in both (hilcam's default; Mitsuba rr_depth = 2) instead of off in both",
    )
    ap.add_argument("--verify-spp", type=int, default=1024)
    ap.add_argument("--verify-width", type=int, default=256)
    ap.add_argument("--verify-tol", type=float, default=0.02, help="limit on rel. RMSE between the renderers")
    ap.add_argument(
        "--verify-mean-tol",
        type=float,
        default=None,
        help="limit on the relative difference of mean radiance (default: half of --verify-tol)",
    )
    ap.add_argument("--verify-only", action="store_true")
    ap.add_argument("--skip-verify", action="store_true")
    ap.add_argument("--quick", action="store_true", help="128x128, spp 1..16, 2 reps, small reference")
    ap.add_argument("--lambertize", action="store_true", help="replace non-Lambert materials by a Lambert (stated albedo)")
    ap.add_argument("--albedo", action="append", default=[], metavar="NAME=V", help="albedo of a lambertized material")
    ap.add_argument("--hilcam", type=Path, default=ROOT / "target" / "release" / "hilcam")
    ap.add_argument("--report", type=Path, metavar="CSV", help="only re-print the table and re-plot a CSV written before")
    args = ap.parse_args()
    if args.report:
        bootstrap()  # for matplotlib
        import vs_mitsuba_criterion as crit

        if crit.is_criterion_csv(args.report):
            rows = crit.read_rows(args.report)
            crit.plot_criterion(rows, crit.report_criterion(rows, args.report.stem), args.report.stem)
            return 0
        with args.report.open() as f:
            rows = [
                {k: (float(v) if k in ("time_s", "rel_rmse", "rel_rmse_raw", "ref_noise") else spp_number(v) if k == "spp" else int(v) if k in ("rep", "width", "height", "depth") else v) for k, v in r.items()}
                for r in csv.DictReader(f)
            ]  # fmt: skip
        plot(rows, report(rows, args.report.stem), args.report.stem)
        return 0
    if args.criterion:
        args.sampler = list(dict.fromkeys(args.sampler or ["independent", "multijitter"]))
        args.spp = args.spp or [1, 2, 4, 8, 16, 32, 64, 128, 256]
        args.width = args.width or (None if args.height else 256)
        args.scenes = args.scenes or [ROOT / "scenes" / "satellite_matte.toml"]
        if args.quick:
            args.width, args.spp, args.reps, args.ref_spp, args.ref_chunks = 128, [1, 2, 4, 8, 16, 64], 4, 256, 2
            args.verify_width, args.verify_spp = 128, 1024
        if args.seeds < 2:
            log("error: --seeds must be >= 2 (16 or more for the issue's count)")
            return 2
    args.sampler = list(dict.fromkeys(args.sampler or ["independent"]))
    args.spp = args.spp or [1, 2, 4, 8, 16, 32, 64]
    args.reps = args.reps or (args.seeds if args.criterion else 3)
    if args.quick and not args.criterion:
        args.width, args.spp, args.reps, args.ref_spp = 128, [1, 2, 4, 8, 16], 2, 256
        args.verify_width, args.verify_spp = 128, 1024
    if not args.scenes:
        args.scenes = [ROOT / "scenes" / "sphere.toml", ROOT / "scenes" / "plate.toml"]

    bootstrap()
    import drjit as dr
    import mitsuba as mi
    import numpy as np

    try:
        mi.set_variant("llvm_ad_mono")
        variant = "llvm_ad_mono"
    except Exception as e:  # noqa: BLE001 — any failure to start the LLVM backend
        bar = "!" * 88
        log(f"{bar}\nWARNING: Mitsuba variant llvm_ad_mono unavailable ({e}).\n"
            f"Falling back to scalar_mono: single-lane, NOT representative of Mitsuba's speed.\n{bar}")  # fmt: skip
        mi.set_variant("scalar_mono")
        variant = "scalar_mono"
    log(f"Mitsuba {mi.__version__} (drjit {dr.__version__}), variant {variant}, "
        f"libLLVM {os.environ.get('DRJIT_LIBLLVM_PATH', '(default)')}; hilcam {args.hilcam}")  # fmt: skip
    if not args.hilcam.exists():
        log(f"error: {args.hilcam} not found: run `cargo build --release` (the wrapper does)")
        return 2
    overrides = {}
    for a in args.albedo:
        k, _, v = a.partition("=")
        overrides[k] = float(v)

    failed = False
    with tempfile.TemporaryDirectory(prefix="vs-mitsuba-") as td:
        tmp = Path(td)
        if not args.skip_verify:
            log("\n== convention checks (fail loudly if the two renderers disagree)")
            asym = make_asymmetric_scene(tmp / "asym")
            jobs = [(asym, [2])] + [(p, args.depth) for p in args.scenes]
            for p, depths in jobs:
                sc = load_scene(p, args.lambertize, overrides)
                hp = hilcam_scene_file(p, sc, tmp)
                for d in depths or [sc.depth]:
                    for c in verify(args, mi, np, hp, sc, d, tmp, args.hilcam):
                        log(f"  [{'ok' if c.ok else 'FAIL'}] {c.name}: {c.value * 100:+.3f} % (limit {c.limit * 100:.2f} %)")
                        failed |= not c.ok
            if args.criterion:
                import vs_mitsuba_criterion as crit

                log("\n== the criterion is `hilcam bench quality`'s (its own frames recounted here)")
                for p in args.scenes:
                    failed |= not crit.check_criterion(args, p, args.width or load_scene(p, args.lambertize, overrides).camera.width, args.hilcam, tmp)
            if failed:
                log("\nFAILED: hilcam and Mitsuba disagree on the conventions; timing skipped.")
                return 1
        if args.verify_only:
            return 0
        for p in args.scenes:
            sc = load_scene(p, args.lambertize, overrides)
            hp = hilcam_scene_file(p, sc, tmp)
            for d in args.depth or [sc.depth]:
                if args.criterion:
                    import vs_mitsuba_criterion as crit

                    crit.bench_criterion(args, mi, np, p, hp, sc, d, tmp, args.hilcam)
                else:
                    bench(args, mi, np, hp, sc, d, tmp, args.hilcam)
    return 0


if __name__ == "__main__":
    try:
        sys.exit(main())
    except ExportError as e:
        print(f"vs_mitsuba: error: {e}", file=sys.stderr)
        sys.exit(2)
