"""What the two Basilisk closed-loop examples share (examples/bsk_loop.py in-process,
examples/bsk_serial_loop.py over the serial link against `hilcam serve`; docs/python.md).

Basilisk propagates two spacecraft in a 400 km circular orbit under the Earth's gravity: a
chaser with a camera and a 1 m sphere target ahead of it. The camera is fixed in the
chaser's Hill frame (boresight along-track), so the pose hilcam gets is the target's
relative position in the camera frame. Each step the frame goes, as an 8-bit PNG, to
Basilisk's own image processing (bsk-opnav's `houghCircles`, class Hough): the circle it
finds gives the target's bearing (its centre) and range (its radius, the sphere's 1 m
known), and a PD controller pushes the chaser (Basilisk's ExtForceTorque) to bring the
target to the image centre at 30 m, closing the loop through pixels only. Basilisk's
truth (the pinhole projection of the relative position, and the sphere's apparent radius)
judges the Hough circle. The frame's radiance-weighted centroid is logged as a
cross-check: for a Lambert sphere at phase angle φ the lit centroid sits 3/8·r·tan φ
toward the sun from the centre's projection (first order in φ).
"""

import math
import os
import struct
import tempfile
import zlib

import numpy as np
from Basilisk.architecture import messaging
from Basilisk.fswAlgorithms import houghCircles
from Basilisk.simulation import extForceTorque, spacecraft
from Basilisk.utilities import SimulationBaseClass, macros, orbitalMotion, simIncludeGravBody

WIDTH = 128
F_PX = WIDTH / (2 * math.tan(math.radians(5.0)))  # 10° field of view: 731.6 px
PITCH_UM = 10.0
RADIUS_M = 1.0  # the sphere target (scenes/meshes/sphere.obj)
GOAL_RANGE_M = 30.0
DT_S = 1.0
CHASER_KG = 100.0
# Camera axes in the chaser's Hill frame (x radial, y along-track, z orbit normal):
# boresight Z = along-track, X = orbit normal, Y = radial (X × Y = Z).
CAM_H = np.array([[0.0, 0.0, 1.0], [1.0, 0.0, 0.0], [0.0, 1.0, 0.0]])


def scene_toml(sphere_obj):
    """A float-output scene (no sensor: frames are radiance) with the sphere target."""
    focal_mm = F_PX * PITCH_UM / 1000.0
    return (
        f"[camera]\nwidth = {WIDTH}\nheight = {WIDTH}\npitch_um = {PITCH_UM}\nfocal_mm = {focal_mm!r}\n"
        f"[[mesh]]\nobj = {str(sphere_obj)!r}\n"
        '[materials.white_paint]\nmodel = "lambert"\nrho = 0.522\n'
        "[render]\nspp = 4\ndepth = 1\nseed = 3\n"
    ).replace("'", '"')


def quat_of(r):
    """Hamilton quaternion [w, x, y, z] of the rotation matrix r (Shepperd)."""
    t = np.trace(r)
    if t > 0:
        s = math.sqrt(t + 1.0) * 2
        q = [0.25 * s, (r[2, 1] - r[1, 2]) / s, (r[0, 2] - r[2, 0]) / s, (r[1, 0] - r[0, 1]) / s]
    else:
        i = int(np.argmax(np.diag(r)))
        j, k = (i + 1) % 3, (i + 2) % 3
        s = math.sqrt(1.0 + r[i, i] - r[j, j] - r[k, k]) * 2
        q = [0.0] * 4
        q[0] = (r[k, j] - r[j, k]) / s
        q[1 + i] = 0.25 * s
        q[1 + j] = (r[j, i] + r[i, j]) / s
        q[1 + k] = (r[k, i] + r[i, k]) / s
    return np.array(q) / np.linalg.norm(q)


class Orbit:
    """Basilisk: chaser and target spacecraft, Earth gravity, a force on the chaser."""

    def __init__(self, rho_h=(-2.0, 60.0, 1.5)):
        self.sim = SimulationBaseClass.SimBaseClass()
        proc = self.sim.CreateNewProcess("dyn")
        proc.addTask(self.sim.CreateNewTask("task", macros.sec2nano(0.1)))
        self.chaser, self.target = spacecraft.Spacecraft(), spacecraft.Spacecraft()
        self.chaser.ModelTag, self.target.ModelTag = "chaser", "target"
        self.chaser.hub.mHub = CHASER_KG
        grav = simIncludeGravBody.gravBodyFactory()
        earth = grav.createEarth()
        earth.isCentralBody = True
        self.force = extForceTorque.ExtForceTorque()
        self.force.ModelTag = "thrust"
        self.chaser.addDynamicEffector(self.force)
        for m in (self.chaser, self.target, self.force):
            self.sim.AddModelToTask("task", m)
        grav.addBodiesTo(self.chaser)
        grav.addBodiesTo(self.target)
        oe = orbitalMotion.ClassicElements()
        oe.a, oe.e, oe.i, oe.Omega, oe.omega, oe.f = 6778.0e3, 0.0, math.radians(51.6), 0.3, 0.0, 0.2
        rc, vc = orbitalMotion.elem2rv(earth.mu, oe)
        rd, vd = orbitalMotion.hill2rv(np.array(rc), np.array(vc), np.array(rho_h), np.zeros(3))
        self.chaser.hub.r_CN_NInit, self.chaser.hub.v_CN_NInit = list(rc), list(vc)
        self.target.hub.r_CN_NInit, self.target.hub.v_CN_NInit = list(rd), list(vd)
        # The sun, fixed in inertial space: 4° off the line from the target back to the
        # chaser at the start (a small phase angle, growing as the Hill frame turns).
        hn = orbitalMotion.hillFrame(np.array(rc), np.array(vc))
        back = hn.T @ np.array([0.0, -1.0, 0.0])
        side = hn.T @ np.array([1.0, 0.0, 0.0])
        self.sun_n = math.cos(math.radians(4.0)) * back + math.sin(math.radians(4.0)) * side
        self.sim.InitializeSimulation()
        self.t = 0.0

    def step(self, accel_h):
        """Apply the chaser acceleration `accel_h` (Hill frame, m/s²) for DT_S."""
        rc, vc, _ = self._states()[0]
        hn = orbitalMotion.hillFrame(rc, vc)
        self.force.extForce_N = list(CHASER_KG * (hn.T @ np.asarray(accel_h)))
        self.t += DT_S
        self.sim.ConfigureStopTime(macros.sec2nano(self.t))
        self.sim.ExecuteSimulation()

    def _states(self):
        out = []
        for sc in (self.chaser, self.target):
            m = sc.scStateOutMsg.read()
            out.append((np.array(m.r_BN_N), np.array(m.v_BN_N), np.array(m.sigma_BN)))
        return out

    def truth(self):
        """(position m, attitude [w,x,y,z], sun) of the target in the camera frame, and
        the target's relative velocity in the Hill frame (Basilisk's truth)."""
        (rc, vc, _), (rd, vd, sigma_d) = self._states()
        rho_h, rhop_h = orbitalMotion.rv2hill(rc, vc, rd, vd)
        hn = orbitalMotion.hillFrame(rc, vc)
        # Target body → camera: camera ← Hill ← inertial ← body (Basilisk's σ_BN: [BN]).
        s = np.asarray(sigma_d)
        s2 = s @ s
        tilde = np.array([[0, -s[2], s[1]], [s[2], 0, -s[0]], [-s[1], s[0], 0]])
        bn = np.eye(3) + (8 * tilde @ tilde - 4 * (1 - s2) * tilde) / (1 + s2) ** 2
        cam_b = CAM_H @ hn @ bn.T
        return CAM_H @ np.asarray(rho_h), quat_of(cam_b), CAM_H @ hn @ self.sun_n, np.asarray(rhop_h)


def measure(img):
    """Radiance-weighted centroid (continuous pixel coordinates) and flux of a frame."""
    img = np.asarray(img, dtype=np.float64)
    flux = img.sum()
    rows, cols = np.indices(img.shape)
    return (cols + 0.5).ravel() @ img.ravel() / flux, (rows + 0.5).ravel() @ img.ravel() / flux, flux


def write_png8(path, img):
    """An 8-bit grayscale PNG of a radiance frame, scaled to its peak (an auto-exposure)."""
    img = np.asarray(img, dtype=np.float64)
    dn = np.clip(np.rint(img * (255.0 / max(float(img.max()), 1e-30))), 0, 255).astype(np.uint8)
    h, w = dn.shape
    raw = b"".join(b"\0" + dn[r].tobytes() for r in range(h))

    def chunk(kind, body):
        return struct.pack(">I", len(body)) + kind + body + struct.pack(">I", zlib.crc32(kind + body))

    with open(path + ".tmp", "wb") as f:
        f.write(b"\x89PNG\r\n\x1a\n" + chunk(b"IHDR", struct.pack(">IIBBBBB", w, h, 8, 0, 0, 0, 0))
                + chunk(b"IDAT", zlib.compress(raw)) + chunk(b"IEND", b""))
    os.replace(path + ".tmp", path)


# houghCircles' parameters for this scene: a 12–25 px disc on black, one circle.
HOUGH = dict(blurrSize=5, cannyThresh=200, voteThresh=20, dpValue=1,
             houghMinDist=WIDTH, houghMinRadius=6, houghMaxRadius=40, expectedCircles=1)


class Hough:
    """Basilisk's houghCircles (bsk-opnav) in its own Basilisk simulation, one update per
    frame. The module reads the frame from the PNG named in its `filename` field (its
    image message is linked to an empty CameraImageMsg, which it requires but then does
    not read) and writes an OpNavCirclesMsg: OpenCV's HOUGH_GRADIENT after the module's
    own threshold and box blur. Its centres are pixel indices; +0.5 makes them continuous
    pixel coordinates (the pixel (i, j) spans [i, i+1] × [j, j+1]), as the truth's."""

    def __init__(self):
        self.dir = tempfile.TemporaryDirectory(prefix="hilcam-hough-")
        self.png = os.path.join(self.dir.name, "frame.png")
        self.sim = SimulationBaseClass.SimBaseClass()
        proc = self.sim.CreateNewProcess("opnav")
        proc.addTask(self.sim.CreateNewTask("image", macros.sec2nano(DT_S)))
        self.module = houghCircles.HoughCircles()
        self.module.ModelTag = "houghCircles"
        for k, v in HOUGH.items():
            setattr(self.module, k, v)
        self.module.filename = self.png
        self.image_msg = messaging.CameraImageMsg().write(messaging.CameraImageMsgPayload())
        self.module.imageInMsg.subscribeTo(self.image_msg)
        self.sim.AddModelToTask("image", self.module)
        self.sim.InitializeSimulation()
        self.k = 0

    def __call__(self, img):
        """(u, v, radius) of the circle found in the frame, in pixels."""
        write_png8(self.png, img)
        self.sim.ConfigureStopTime(macros.sec2nano(self.k * DT_S))
        self.sim.ExecuteSimulation()
        self.k += 1
        m = self.module.opnavCirclesOutMsg.read()
        if not m.valid:
            raise RuntimeError("houghCircles found no circle in frame %d" % (self.k - 1))
        c = list(m.circlesCenters)
        return c[0] + 0.5, c[1] + 0.5, float(m.circlesRadii[0])

    def close(self):
        self.dir.cleanup()


def range_of_radius(r_px):
    """The range at which the 1 m sphere's limb is r_px from its centre's image: its
    angular radius asin(R/d) seen at tan⁻¹(r/f) on the boresight."""
    return RADIUS_M / math.sin(math.atan(r_px / F_PX))


def radius_of(position):
    """The sphere's apparent radius in pixels on the boresight (truth for the Hough radius)."""
    return F_PX * math.tan(math.asin(RADIUS_M / np.linalg.norm(position)))


def predicted(position, sun):
    """Where the lit centroid should be: the pinhole projection of the centre, moved
    3/8·r·tan φ toward the sun's side (first order in the phase angle φ)."""
    u = WIDTH / 2 + F_PX * position[0] / position[2]
    v = WIDTH / 2 + F_PX * position[1] / position[2]
    to_cam = -position / np.linalg.norm(position)
    phase = math.acos(max(-1.0, min(1.0, float(to_cam @ sun))))
    across = sun - (sun @ to_cam) * to_cam  # the sun's side, perpendicular to the line of sight
    n = np.linalg.norm(across[:2])
    r_px = F_PX * RADIUS_M / np.linalg.norm(position)
    shift = 0.375 * r_px * math.tan(phase)
    du, dv = (across[0] / n * shift, across[1] / n * shift) if n > 0 else (0.0, 0.0)
    return (u, v), (u + du, v + dv), phase


class Controller:
    """PD on the measured target position (bearing from the Hough centre × range from its
    radius), Hill frame: lateral offsets to zero, range to GOAL_RANGE_M. ω = 0.2 rad/s,
    critically damped."""

    def __init__(self):
        self.last = None
        self.kp, self.kd = 0.2**2, 2 * 0.2

    def __call__(self, u, v, r_px):
        rng = range_of_radius(r_px)
        z = rng / math.sqrt(1 + ((u - WIDTH / 2) / F_PX) ** 2 + ((v - WIDTH / 2) / F_PX) ** 2)
        rel_cam = np.array([(u - WIDTH / 2) / F_PX * z, (v - WIDTH / 2) / F_PX * z, z])
        rel_h = CAM_H.T @ rel_cam
        goal = np.array([0.0, GOAL_RANGE_M, 0.0])
        rate = np.zeros(3) if self.last is None else (rel_h - self.last) / DT_S
        self.last = rel_h
        # ρ'' = −a_chaser: push the chaser toward where the target should be.
        return self.kp * (rel_h - goal) + self.kd * rate, rng


def run(render, steps=60):
    """Close the loop for `steps` steps; `render(k, position, attitude, sun)` returns the
    frame's radiance. Returns one dict per step (truth, measurement, prediction)."""
    orbit, hough, ctl = Orbit(), Hough(), Controller()
    log = []
    try:
        for k in range(steps):
            pos, q, sun, _ = orbit.truth()
            img = render(k, orbit.t, pos, q, sun)
            hu, hv, hr = hough(img)
            accel, rng = ctl(hu, hv, hr)
            cu, cv, _ = measure(img)
            (tu, tv), (pu, pv), phase = predicted(pos, sun)
            log.append(dict(step=k, t=orbit.t, range_m=float(np.linalg.norm(pos)), range_est_m=rng,
                            hough=[hu, hv], hough_r_px=hr, truth_r_px=radius_of(pos),
                            centroid=[float(cu), float(cv)], truth=[tu, tv], predicted=[pu, pv],
                            phase_deg=math.degrees(phase), accel=[float(a) for a in accel]))
            orbit.step(accel)
    finally:
        hough.close()
    return log
