#!/usr/bin/env python3
"""Generate the shipped trajectories (scenes/trajectories/*.csv); stdlib only.

Target: a ~5 m satellite at the origin of an inertial frame I. Camera: 1024x1024,
~20 deg field of view, boresight +Z (computer-vision camera frame, docs/trajectory.md).

approach.csv  : 1000 m -> 10 m along the line of sight in 1200 s (range decays
                exponentially, i.e. a constant relative closing rate), camera
                inertially fixed, target tumbling slowly; sun fixed (phase ~37 deg).
flyaround.csv : camera circles the target once in 600 s at 20 deg elevation, range
                40 +- 8 m, boresight always on the target; the target spins slowly
                about its body z axis, so the sun moves both in the camera frame and
                over the target's body. Has velocity (d position / dt, camera frame)
                and angular rate (omega with dq/dt = 1/2 omega (x) q, camera frame).
Samples every 0.5 s (exact in binary and decimal).
"""
import math
import os

OUT = os.path.join(os.path.dirname(os.path.abspath(__file__)), "..", "scenes", "trajectories")


def norm(v):
    n = math.sqrt(sum(c * c for c in v))
    return tuple(c / n for c in v)


def cross(a, b):
    return (a[1] * b[2] - a[2] * b[1], a[2] * b[0] - a[0] * b[2], a[0] * b[1] - a[1] * b[0])


def matmul(a, b):
    return [[sum(a[i][k] * b[k][j] for k in range(3)) for j in range(3)] for i in range(3)]


def transpose(m):
    return [[m[j][i] for j in range(3)] for i in range(3)]


def matvec(m, v):
    return tuple(sum(m[i][k] * v[k] for k in range(3)) for i in range(3))


def axis_angle(axis, ang):
    x, y, z = norm(axis)
    c, s, C = math.cos(ang), math.sin(ang), 1 - math.cos(ang)
    return [[c + x * x * C, x * y * C - z * s, x * z * C + y * s],
            [y * x * C + z * s, c + y * y * C, y * z * C - x * s],
            [z * x * C - y * s, z * y * C + x * s, c + z * z * C]]


def quat(m):
    """Unit quaternion (w, x, y, z), w >= 0, of a rotation matrix."""
    tr = m[0][0] + m[1][1] + m[2][2]
    if tr > 0:
        s = math.sqrt(tr + 1.0) * 2
        q = (0.25 * s, (m[2][1] - m[1][2]) / s, (m[0][2] - m[2][0]) / s, (m[1][0] - m[0][1]) / s)
    elif m[0][0] > m[1][1] and m[0][0] > m[2][2]:
        s = math.sqrt(1.0 + m[0][0] - m[1][1] - m[2][2]) * 2
        q = ((m[2][1] - m[1][2]) / s, 0.25 * s, (m[0][1] + m[1][0]) / s, (m[0][2] + m[2][0]) / s)
    elif m[1][1] > m[2][2]:
        s = math.sqrt(1.0 + m[1][1] - m[0][0] - m[2][2]) * 2
        q = ((m[0][2] - m[2][0]) / s, (m[0][1] + m[1][0]) / s, 0.25 * s, (m[1][2] + m[2][1]) / s)
    else:
        s = math.sqrt(1.0 + m[2][2] - m[0][0] - m[1][1]) * 2
        q = ((m[1][0] - m[0][1]) / s, (m[0][2] + m[2][0]) / s, (m[1][2] + m[2][1]) / s, 0.25 * s)
    q = norm(q)
    return q if q[0] >= 0 else tuple(-c for c in q)


def fmt(vals):
    return ",".join(repr(float(v)) for v in vals)


def approach():
    T, r0, r1 = 1200.0, 1000.0, 10.0
    sun = norm((-0.5, -0.3, -0.8))
    rows = ["time_s,px,py,pz,qw,qx,qy,qz,sx,sy,sz"]
    for k in range(int(T / 0.5) + 1):
        t = k * 0.5
        r = r0 * (r1 / r0) ** (t / T)
        # a small pointing wander, under 0.3 deg off boresight
        off = (0.004 * math.sin(2 * math.pi * t / 170.0), 0.003 * math.cos(2 * math.pi * t / 230.0))
        p = norm((off[0], off[1], 1.0))
        pos = tuple(c * r for c in p)
        q = quat(axis_angle((0.3, 1.0, 0.2), math.radians(0.15) * t))
        rows.append(fmt((t, *pos, *q, *sun)))
    return rows


def flyaround_state(t):
    T, elev, spin = 600.0, math.radians(20.0), 0.004  # spin: rad/s about body z
    th = 2 * math.pi * t / T
    r = 40.0 + 8.0 * math.sin(2 * math.pi * t / 300.0)
    c = tuple(r * v for v in (math.cos(elev) * math.cos(th), math.cos(elev) * math.sin(th), math.sin(elev)))
    zc = norm(tuple(-v for v in c))
    xc = norm(cross((0.0, 0.0, 1.0), zc))
    yc = cross(zc, xc)
    R_IC = [[xc[i], yc[i], zc[i]] for i in range(3)]  # camera -> inertial
    R_IB = axis_angle((0.0, 0.0, 1.0), spin * t)  # body -> inertial
    R_CB = matmul(transpose(R_IC), R_IB)
    pos = matvec(transpose(R_IC), tuple(-v for v in c))
    sun = matvec(transpose(R_IC), norm((1.0, 0.2, 0.3)))
    return R_CB, pos, sun


def flyaround():
    rows = ["time_s,px,py,pz,qw,qx,qy,qz,sx,sy,sz,vx,vy,vz,wx,wy,wz"]
    h = 1e-3
    for k in range(int(600.0 / 0.5) + 1):
        t = k * 0.5
        R, pos, sun = flyaround_state(t)
        Rp, pp, _ = flyaround_state(t + h)
        Rm, pm, _ = flyaround_state(t - h)
        vel = tuple((a - b) / (2 * h) for a, b in zip(pp, pm))
        # dR/dt R^T = [omega]x (camera frame)
        dR = [[(Rp[i][j] - Rm[i][j]) / (2 * h) for j in range(3)] for i in range(3)]
        W = matmul(dR, transpose(R))
        w = ((W[2][1] - W[1][2]) / 2, (W[0][2] - W[2][0]) / 2, (W[1][0] - W[0][1]) / 2)
        rows.append(fmt((t, *pos, *quat(R), *sun, *vel, *w)))
    return rows


def main():
    os.makedirs(OUT, exist_ok=True)
    for name, rows in (("approach", approach()), ("flyaround", flyaround())):
        path = os.path.join(OUT, name + ".csv")
        with open(path, "w") as f:
            f.write("# hilcam trajectory (docs/trajectory.md); generated by scripts/gen-trajectories.py\n")
            f.write("\n".join(rows) + "\n")
        print(f"{path}: {len(rows) - 1} samples")


if __name__ == "__main__":
    main()
