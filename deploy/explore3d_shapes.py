#!/usr/bin/python3
"""Compares the live voxmap's logged 3D primitives (hemm-operator --shape-log:
DIR/primitives.csv, or hemm-shape3d-replay's output) with the scene's true
geometry (the MJCF's box, cylinder and sphere geoms inside the truth region).

For every logged primitive: points sampled over its surface (2 mm apart),
each one's signed distance to the true solid (the union of the scene's geoms):
`out` is the largest distance of a primitive surface point out in true free
space (solid added where there is none: too hard), `in` the deepest one
inside a true solid (a face sunk into the object: too soft or not felt),
`bad` the share of its surface farther than --tol from the true surface.
Prints, per rebuild's primitive, the nearest true geom and these figures;
with --summary one line per distinct (geom, kind) over the run with how
many rebuilds held a bad one.

Usage: explore3d_shapes.py SCENE.xml PRIMITIVES.csv [--region x0 y0 z0 x1 y1 z1] [--tol 0.005] [--summary]
"""
import argparse
import csv
import math
import sys
import xml.etree.ElementTree as ET

import numpy as np


def euler_xyz(e):
    # MuJoCo's default eulerseq "xyz": intrinsic rotations about x, then y', then z''.
    cx, cy, cz = (math.cos(a) for a in e)
    sx, sy, sz = (math.sin(a) for a in e)
    rx = np.array([[1, 0, 0], [0, cx, -sx], [0, sx, cx]])
    ry = np.array([[cy, 0, sy], [0, 1, 0], [-sy, 0, cy]])
    rz = np.array([[cz, -sz, 0], [sz, cz, 0], [0, 0, 1]])
    return rx @ ry @ rz


def quat(q):
    w, x, y, z = q / np.linalg.norm(q)
    return np.array([[1 - 2 * (y * y + z * z), 2 * (x * y - z * w), 2 * (x * z + y * w)],
                     [2 * (x * y + z * w), 1 - 2 * (x * x + z * z), 2 * (y * z - x * w)],
                     [2 * (x * z - y * w), 2 * (y * z + x * w), 1 - 2 * (x * x + y * y)]])


def frame_of(el):
    p = np.array([float(v) for v in el.get("pos", "0 0 0").split()])
    R = np.eye(3)
    if el.get("euler"):
        R = euler_xyz([float(v) for v in el.get("euler").split()])
    elif el.get("quat"):
        R = quat(np.array([float(v) for v in el.get("quat").split()]))
    elif el.get("axisangle") or el.get("zaxis") or el.get("xyaxes"):
        raise SystemExit(f"explore3d_shapes: geom/body orientation {el.attrib} not supported")
    return p, R


def scene_geoms(path):
    root = ET.parse(path).getroot()
    geoms = []
    # A geom's type from its class's defaults when it names none (MuJoCo's default: sphere).
    class_type = {}

    def defaults(el, inherited):
        t = inherited
        g = el.find("geom")
        if g is not None and g.get("type"):
            t = g.get("type")
        class_type[el.get("class", "main")] = t
        for ch in el.findall("default"):
            defaults(ch, t)

    for d in root.findall("default"):
        defaults(d, "sphere")

    def walk(el, p0, R0, cls):
        for ch in el:
            if ch.tag == "body":
                p, R = frame_of(ch)
                walk(ch, p0 + R0 @ p, R0 @ R, ch.get("childclass", cls))
            elif ch.tag == "geom":
                t = ch.get("type") or class_type.get(ch.get("class", cls), class_type.get("main", "sphere"))
                if t not in ("box", "cylinder", "sphere"):
                    continue
                p, R = frame_of(ch)
                size = [float(v) for v in ch.get("size", "0").split()]
                geoms.append({"name": ch.get("name", "?"), "type": t, "c": p0 + R0 @ p, "R": R0 @ R, "size": size})

    wb = root.find("worldbody")
    walk(wb, np.zeros(3), np.eye(3), "main")
    return geoms


def sdf_local(kind, h, x):
    """Signed distance (positive outside) of points x (N x 3, the shape's frame)."""
    if kind == "box":
        q = np.abs(x) - h
        return np.linalg.norm(np.maximum(q, 0), axis=1) + np.minimum(q.max(axis=1), 0)
    if kind == "cylinder":
        r, hh = h[0], h[2]
        a = np.hypot(x[:, 0], x[:, 1]) - r
        b = np.abs(x[:, 2]) - hh
        return np.hypot(np.maximum(a, 0), np.maximum(b, 0)) + np.minimum(np.maximum(a, b), 0)
    return np.linalg.norm(x, axis=1) - h[0]


def geom_half(g):
    s = g["size"]
    if g["type"] == "box":
        return np.array(s[:3])
    if g["type"] == "cylinder":
        return np.array([s[0], s[0], s[1]])
    return np.array([s[0]] * 3)


def true_sdf(geoms, x):
    d = np.full(len(x), 1e9)
    for g in geoms:
        d = np.minimum(d, sdf_local(g["type"], geom_half(g), (x - g["c"]) @ g["R"]))
    return d


def surface_points(kind, h, step=0.002):
    """Points on the primitive's surface in its frame, about `step` apart."""
    pts = []
    if kind == "box":
        for a in range(3):
            b, c = [i for i in range(3) if i != a]
            ub = np.arange(-h[b], h[b] + 1e-9, step)
            uc = np.arange(-h[c], h[c] + 1e-9, step)
            B, C = np.meshgrid(ub, uc)
            for s in (-1, 1):
                P = np.zeros((B.size, 3))
                P[:, a] = s * h[a]
                P[:, b] = B.ravel()
                P[:, c] = C.ravel()
                pts.append(P)
    elif kind == "cylinder":
        r, hh = h[0], h[2]
        n = max(8, int(2 * math.pi * r / step))
        t = np.linspace(0, 2 * math.pi, n, endpoint=False)
        z = np.arange(-hh, hh + 1e-9, step)
        T, Z = np.meshgrid(t, z)
        pts.append(np.stack([r * np.cos(T.ravel()), r * np.sin(T.ravel()), Z.ravel()], axis=1))
        for rr in np.arange(0, r, step):
            m = max(1, int(2 * math.pi * rr / step))
            tt = np.linspace(0, 2 * math.pi, m, endpoint=False)
            for s in (-1, 1):
                pts.append(np.stack([rr * np.cos(tt), rr * np.sin(tt), np.full(m, s * hh)], axis=1))
    else:
        r = h[0]
        n = max(50, int(4 * math.pi * r * r / step ** 2))
        i = np.arange(n) + 0.5
        phi = np.arccos(1 - 2 * i / n)
        th = math.pi * (1 + 5 ** 0.5) * i
        pts.append(r * np.stack([np.cos(th) * np.sin(phi), np.sin(th) * np.sin(phi), np.cos(phi)], axis=1))
    return np.concatenate(pts)


def main():
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("scene")
    ap.add_argument("primitives")
    ap.add_argument("--region", nargs=6, type=float)
    ap.add_argument("--tol", type=float, default=0.005)
    ap.add_argument("--summary", action="store_true")
    a = ap.parse_args()
    geoms = scene_geoms(a.scene)
    if a.region:
        lo, hi = np.array(a.region[:3]), np.array(a.region[3:])
        geoms = [g for g in geoms if np.all(g["c"] >= lo - 0.7) and np.all(g["c"] <= hi + 0.7)]
    rows = list(csv.DictReader(open(a.primitives)))
    out_rows = []
    for r in rows:
        if r["kind"] not in ("box", "cylinder", "sphere"):
            continue
        c = np.array([float(r[k]) for k in ("cx", "cy", "cz")])
        z = np.array([float(r[k]) for k in ("zx", "zy", "zz")])
        x = np.array([float(r[k]) for k in ("xx", "xy", "xz")])
        R = np.stack([x, np.cross(z, x), z], axis=1)
        h = np.array([float(r[k]) for k in ("hx", "hy", "hz")])
        P = surface_points(r["kind"], h) @ R.T + c
        d = true_sdf(geoms, P)
        near = min(geoms, key=lambda g: np.linalg.norm(g["c"] - c))
        out_rows.append({
            "build": int(r["build"]), "kind": r["kind"], "geom": near["name"], "c": c, "h": h, "z": z,
            "out": float(d.max()), "in": float(-d.min()), "bad": float(np.mean(np.abs(d) > a.tol)),
            "kept": r.get("kept", "0"), "rms": float(r["rms"]), "inliers": r["inliers"], "points": r["points"],
            "faces": r.get("faces", ""), "arc": r.get("arc", "")})
    if not a.summary:
        print("build,kind,geom,cx,cy,cz,zx,zy,zz,hx,hy,hz,out_mm,in_mm,bad_share,kept,rms_mm,inliers,points,faces,arc")
        for o in out_rows:
            print(f"{o['build']},{o['kind']},{o['geom']},{o['c'][0]:.4f},{o['c'][1]:.4f},{o['c'][2]:.4f},"
                  f"{o['z'][0]:.3f},{o['z'][1]:.3f},{o['z'][2]:.3f},{o['h'][0]:.4f},{o['h'][1]:.4f},{o['h'][2]:.4f},"
                  f"{1e3 * o['out']:.1f},{1e3 * o['in']:.1f},{o['bad']:.3f},{o['kept']},{1e3 * o['rms']:.2f},"
                  f"{o['inliers']},{o['points']},{o['faces']},{o['arc']}")
        return
    builds = sorted({int(r["build"]) for r in rows})
    print(f"{len(builds)} rebuilds, {len(out_rows)} primitives; bad: more than {100 * 0.1:.0f} % of the surface "
          f"beyond {1e3 * a.tol:.0f} mm of the true one")
    print("| true geom | kind | rebuilds | bad rebuilds | worst out mm | worst in mm | median bad share |")
    print("|---|---|--:|--:|--:|--:|--:|")
    keys = sorted({(o["geom"], o["kind"]) for o in out_rows})
    for k in keys:
        s = [o for o in out_rows if (o["geom"], o["kind"]) == k]
        bad = [o for o in s if o["bad"] > 0.1]
        print(f"| {k[0]} | {k[1]} | {len(s)} | {len(bad)} | {1e3 * max(o['out'] for o in s):.1f} | "
              f"{1e3 * max(o['in'] for o in s):.1f} | {np.median([o['bad'] for o in s]):.2f} |")


if __name__ == "__main__":
    sys.exit(main())
