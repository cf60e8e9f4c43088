"""A planet given per frame from Python (Renderer.render(planet=…)): it moves, it is
checked as a scene's [planet], and at 1 AU at its true size the numbers stay finite and
right (docs/python.md, "A moving planet")."""

import math

import numpy as np
import pytest

import hilcam
from pngpfm import read_pfm

AU = 1.495978707e11
EARTH_R = 6.371e6
E_SUN = 593.1  # the scene's band irradiance, W/m²
# A narrow camera (the paper's 16 µm pixels behind a 6 m focal length), 128 x 128: the Earth
# at 1 AU spans ~32 pixels. No sensor: the radiance is compared with the algebra.
CAMERA = """[camera]
width = 128
height = 128
pitch_um = 16.0
focal_mm = 6000.0
"""
TARGET_ASIDE = [0.0, 1.0e4, 22.0]  # the satellite far outside this camera's field
SUN_BEHIND = [0.0, 0.0, -1.0]  # full phase: the sun behind the camera


@pytest.fixture(scope="module")
def renderer(root, tmp_path_factory):
    cam = tmp_path_factory.mktemp("cam") / "narrow.toml"
    cam.write_text(CAMERA)
    scene = hilcam.Scene.load(str(root / "scenes/satellite.toml"))
    return hilcam.Renderer(scene, hilcam.Camera.load(str(cam)), spp=4, seed=1)


def disc(r, distance, radius, centre_px=(0.0, 0.0)):
    f_px = 6.0 / 16e-6
    c = [centre_px[0] / f_px * distance, centre_px[1] / f_px * distance, distance]
    planet = hilcam.Planet(c, radius_m=radius, albedo=0.3)
    return r.render(TARGET_ASIDE, SUN_BEHIND, planet=planet, sensor=False).radiance


def test_the_earth_at_one_au_has_its_true_size_and_radiance(renderer):
    img = disc(renderer, AU, EARTH_R)
    assert np.all(np.isfinite(img)) and img.min() >= 0
    # Lambert at full phase: L = ρ·E·μ₀/π, μ₀ = 1 at the disc's centre.
    centre = img[63:65, 63:65].mean()
    assert abs(centre / (0.3 * E_SUN / math.pi) - 1) < 0.01, centre
    # Flux over the disc: Σ L·Ω_px = (2/3)·ρ·E·(R/d)² (the mean μ₀ over a disc is 2/3).
    omega_px = (16e-6 / 6.0) ** 2
    flux = img.sum(dtype=np.float64) * omega_px
    expected = 2 / 3 * 0.3 * E_SUN * (EARTH_R / AU) ** 2
    assert abs(flux / expected - 1) < 0.01, (flux, expected)
    # Its radius in pixels, tan(asin(R/d)) · f / pitch = 15.97 px, from the radiance-weighted
    # mean of ρ² about the centre: 0.4 r² for L ∝ √(1 − ρ²/r²), plus 1/6 px² of box filter.
    r_px = math.tan(math.asin(EARTH_R / AU)) * 6.0 / 16e-6
    rows, cols = np.indices(img.shape)
    rho2 = (cols + 0.5 - 64) ** 2 + (rows + 0.5 - 64) ** 2
    r_est = math.sqrt(((rho2 * img).sum() / img.sum() - 1 / 6) / 0.4)
    assert abs(r_est / r_px - 1) < 0.01, (r_est, r_px)


def test_one_au_is_the_same_picture_as_a_small_sphere_near_by(renderer):
    far = disc(renderer, AU, EARTH_R)
    near = disc(renderer, AU / 1e4, EARTH_R / 1e4)
    assert np.abs(far - near).max() <= 1e-4 * far.max()


def test_the_planet_moves_from_frame_to_frame(renderer):
    # Its centre on pixel offsets (+20, −10) then (−30, +25) from the image centre.
    for dx, dy in ((20.0, -10.0), (-30.0, 25.0)):
        img = disc(renderer, AU, EARTH_R, (dx, dy))
        rows, cols = np.nonzero(img)
        w = img[rows, cols]
        cx, cy = (cols + 0.5) @ w / w.sum(), (rows + 0.5) @ w / w.sum()
        assert abs(cx - (64 + dx)) < 0.2 and abs(cy - (64 + dy)) < 0.2, (cx, cy, dx, dy)
    # Without one the scene's own (the satellite scene has none): black sky.
    none = renderer.render(TARGET_ASIDE, SUN_BEHIND, sensor=False).radiance
    assert none.max() == 0


def test_a_planet_is_checked_as_a_scene_planet_is(root, cli, tmp_path):
    bad = tmp_path / "inside.toml"
    text = (root / "scenes/sphere.toml").read_text().replace("../", str(root) + "/").replace('obj = "meshes/', f'obj = "{root}/scenes/meshes/')
    bad.write_text(text + '\n[planet]\nbody = "earth"\ncenter_m = [0.0, 0.0, 1.0e6]\n')
    p = cli("render", str(bad), "--out", str(tmp_path / "x.png"), check=False)
    with pytest.raises(hilcam.HilcamError) as e:
        hilcam.Planet([0.0, 0.0, 1.0e6], body="earth")
    assert p.returncode != 0 and p.stderr.strip().endswith(str(e.value)), (p.stderr, str(e.value))
    assert str(e.value).startswith("planet.center_m: the camera is inside the planet")
    with pytest.raises(hilcam.HilcamError, match=r"^planet.center_m: must be finite and within 1.5e13 m"):
        hilcam.Planet([0.0, 0.0, 1e14], body="moon")
    with pytest.raises(hilcam.HilcamError, match=r"^planet.body: unknown body `mars`"):
        hilcam.Planet([0.0, 0.0, AU], body="mars")
    with pytest.raises(hilcam.HilcamError, match=r"^planet.radius_m: give radius_m or body"):
        hilcam.Planet([0.0, 0.0, AU], albedo=0.3)
    with pytest.raises(hilcam.HilcamError, match=r"^planet.albedo: must be a finite number in \[0, 1\]"):
        hilcam.Planet([0.0, 0.0, AU], body="earth", albedo=1.5)
    p = hilcam.Planet([0.0, 0.0, AU], body="moon", model="lommel-seeliger")
    assert p.radius_m == 1.7374e6 and p.albedo == 0.11 and p.center_m == [0.0, 0.0, AU]


def test_a_trajectory_row_with_a_planet_replays_to_the_module_frame_with_that_planet(root, cli, tmp_path):
    # The same planet from the two ends: `hilcam replay` of trajectory rows whose
    # plx,ply,plz move the scene's [planet], and Renderer.render(planet=…) at each row.
    scene = tmp_path / "s.toml"
    scene.write_text(
        "[camera]\nwidth = 64\nheight = 64\npitch_um = 10.0\nfocal_mm = 2.0\n"
        f'[[mesh]]\nobj = "{root}/scenes/meshes/sphere.obj"\n'
        '[materials.white_paint]\nmodel = "lambert"\nrho = 0.5\n[render]\nspp = 2\ndepth = 2\n'
        '[planet]\nbody = "moon"\ncenter_m = [0.0, 0.0, 4.0e8]\n'
    )
    rows = [([0.5, 0.0, 12.0], [-3.0e6, 2.5e6, 2.0e7]), ([0.4, 0.1, 12.0], [-2.5e6, 3.0e6, 2.1e7])]
    sun = [0.6, 0.0, -0.8]
    csv = tmp_path / "t.csv"
    csv.write_text("time_s,px,py,pz,qw,qx,qy,qz,sx,sy,sz,plx,ply,plz\n" + "".join(
        ",".join(str(v) for v in [k, *p, 1, 0, 0, 0, *sun, *c]) + "\n" for k, (p, c) in enumerate(rows)))
    cli("replay", "--trajectory", str(csv), "--scene", str(scene), "--format", "pfm", "--out", str(tmp_path / "out"))
    r = hilcam.Renderer(hilcam.Scene.load(str(scene)))
    for k, (p, c) in enumerate(rows):
        img = r.render(p, sun, planet=hilcam.Planet(c, body="moon"), frame=k, sensor=False).radiance
        replayed = read_pfm(tmp_path / "out" / f"frame_{k:010}.pfm")
        assert replayed[:, :20].max() > 0, "the Moon is not in the left part of the frame"
        assert np.array_equal(img, replayed), k
