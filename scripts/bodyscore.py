"""Scoring a scan of a virtual body against its exact surface, with numpy and Open3D alone on
the files the programs write (nothing of mirrorscan's code): the body's exact surface and
truth (`mirrorscan sim subject --out subject.ply --truth meta.json`), the processed mesh and
cloud (`mirrorscan process`), and the sim's truth peaks (`sim scan --truth`).

Used by scripts/coverage (one body) and scripts/population-figures (all of them).
"""
import importlib.machinery
import importlib.util
import json
import os

import numpy as np
import open3d as o3d


def _load_score():
    path = os.path.join(os.path.dirname(os.path.abspath(__file__)), "score-reconstruction")
    loader = importlib.machinery.SourceFileLoader("score_reconstruction", path)
    module = importlib.util.module_from_spec(importlib.util.spec_from_loader(loader.name, loader))
    loader.exec_module(module)
    return module


SCORE = _load_score()  # the archive reader and truth matching of scripts/score-reconstruction

# Regions of the body, in the order the tables list them (docs/virtual-cabinet.md,
# "Coverage by region", says how each is bounded).
REGIONS = ["head", "neck", "shoulders", "chest and back", "under the arms", "abdomen and hips",
           "crotch and inner thighs", "upper arms", "forearms and hands", "legs", "feet"]
PARTS = ["trunk", "left_arm", "right_arm", "left_leg", "right_leg"]
SEEN_MM = 5.0


def read_cloud_xyz(path):
    """x, y, z of a binary little-endian PLY whose first three properties are float x y z."""
    with open(path, "rb") as f:
        header = b""
        while not header.endswith(b"end_header\n"):
            header += f.readline()
        lines = header.decode().splitlines()
        count = int(next(l.split()[2] for l in lines if l.startswith("element vertex")))
        sizes = {"float": 4, "uchar": 1, "int": 4, "uint": 4, "double": 8, "ushort": 2,
                 "short": 2, "char": 1, "float32": 4, "uint8": 1, "int32": 4}
        props = [l.split() for l in lines if l.startswith("property")]
        stride = sum(sizes[p[1]] for p in props)
        data = np.frombuffer(f.read(count * stride), dtype=np.uint8).reshape(count, stride)
    return np.ascontiguousarray(data[:, :12]).view("<f4").reshape(count, 3).astype(np.float64)


def surface_samples(mesh, per_mm2=0.25, soles=False, seed=1):
    """Area-weighted samples on the mesh: (points, triangle index, unit normal), without the
    soles (faces on the floor, facing down) unless asked."""
    v = np.asarray(mesh.vertices)
    t = np.asarray(mesh.triangles)
    a, b, c = v[t[:, 0]], v[t[:, 1]], v[t[:, 2]]
    cross = np.cross(b - a, c - a)
    area = 0.5 * np.linalg.norm(cross, axis=1)
    normal = cross / np.maximum(2 * area, 1e-12)[:, None]
    keep = np.ones(len(t), bool)
    if not soles:
        keep = ~((np.maximum(np.maximum(a[:, 2], b[:, 2]), c[:, 2]) < 1.0) & (normal[:, 2] < -0.9))
    rng = np.random.default_rng(seed)
    counts = rng.poisson(area[keep] * per_mm2)
    idx = np.repeat(np.nonzero(keep)[0], counts)
    r1, r2 = rng.random(len(idx)), rng.random(len(idx))
    s = np.sqrt(r1)
    points = (1 - s)[:, None] * a[idx] + (s * (1 - r2))[:, None] * b[idx] + (s * r2)[:, None] * c[idx]
    return points, idx, normal[idx]


class Distance:
    """Distance from points to a mesh, as the distance to the nearest of the mesh's
    area-weighted samples at 1 per mm^2 (at most ~0.7 mm more than the exact distance; Open3D
    0.16's exact RaycastingScene.compute_distance aborts on an Eigen assertion on some of
    these meshes). Built once per mesh."""

    def __init__(self, mesh):
        points, _, _ = surface_samples(mesh, 1.0, soles=True)
        self.cloud = o3d.geometry.PointCloud(o3d.utility.Vector3dVector(points))

    def __call__(self, points):
        if len(points) == 0:
            return np.zeros(0)
        query = o3d.geometry.PointCloud(o3d.utility.Vector3dVector(np.asarray(points, float)))
        return np.asarray(query.compute_point_cloud_distance(self.cloud))


def triangle_parts(meta, triangle_count):
    """Each triangle's part index (PARTS) from the subject's metadata "parts" ranges."""
    part = np.zeros(triangle_count, np.int8)
    for p in meta["parts"]:
        if p["name"] in PARTS:
            part[p["first_triangle"]:p["first_triangle"] + p["triangle_count"]] = PARTS.index(p["name"])
    return part


def upright(meta, points):
    """World points in the body's upright frame (z up from the floor, facing -y, +x the
    body's left; yaw, lean and position undone)."""
    m = np.array(meta["landmarks"]["world_from_upright"]).reshape(4, 4, order="F")
    inv = np.linalg.inv(m)
    p = np.asarray(points, float).reshape(-1, 3)
    return p @ inv[:3, :3].T + inv[:3, 3]


def classify(meta, points, part):
    """Each point's region index (REGIONS), from its part (the body model's skeleton) and its
    height and side in the upright frame, bounded by the skeleton's landmarks and the
    stature's proportions (docs/virtual-cabinet.md)."""
    lm = meta["landmarks"]
    H = meta["params"]["stature_mm"]
    up = upright(meta, points)
    x, z = up[:, 0], up[:, 2]
    joint = {k: upright(meta, lm[k]) for k in ("shoulder_joint", "elbow_joint", "wrist_joint",
                                                  "hip_joint", "knee_joint", "ankle_joint", "side_neck")}
    crotch_z = upright(meta, lm["crotch"])[0, 2]
    st = lm["stations_z_mm"]
    chin_z, armpit_z = 0.870 * H, 0.748 * H
    neck_base_z = joint["side_neck"][:, 2].mean()
    neck_half = np.abs(joint["side_neck"][:, 0]).mean()
    region = np.full(len(points), -1, np.int8)
    R = {name: i for i, name in enumerate(REGIONS)}

    trunk = part == 0
    arm = (part == 1) | (part == 2)
    leg = (part == 3) | (part == 4)
    side = np.where((part == 1) | (part == 3), 0, 1)  # landmarks' [left, right]

    # The trunk's half width in 10 mm slabs: where the under-arm band starts.
    slab = np.floor(z / 10).astype(int)
    half = np.zeros(len(points))
    if trunk.any():
        order = np.unique(slab[trunk])
        widest = {s: np.abs(x[trunk & (slab == s)]).max() for s in order}
        half[trunk] = [widest[s] for s in slab[trunk]]

    def arm_axis_x(s, zz):
        """The arm's axis (shoulder-elbow-wrist) at height zz: its |x|."""
        sh, el, wr = joint["shoulder_joint"][s], joint["elbow_joint"][s], joint["wrist_joint"][s]
        upper = zz > el[2]
        a = np.where(upper[:, None], sh, el)
        b = np.where(upper[:, None], el, wr)
        t = (zz - a[:, 2]) / np.where(np.abs(b[:, 2] - a[:, 2]) < 1e-6, 1e-6, b[:, 2] - a[:, 2])
        return np.abs(a[:, 0] + t * (b[:, 0] - a[:, 0]))

    def leg_axis_x(s, zz):
        hp, kn, an = joint["hip_joint"][s], joint["knee_joint"][s], joint["ankle_joint"][s]
        upper = zz > kn[2]
        a = np.where(upper[:, None], hp, kn)
        b = np.where(upper[:, None], kn, an)
        t = (zz - a[:, 2]) / (b[:, 2] - a[:, 2])
        return np.abs(a[:, 0] + t * (b[:, 0] - a[:, 0]))

    top_band = armpit_z + 0.015 * H
    region[trunk & (z > chin_z)] = R["head"]
    region[trunk & (z <= chin_z) & (z > neck_base_z) & (np.abs(x) < 1.5 * neck_half)] = R["neck"]
    rest = trunk & (region < 0)
    region[rest & (z > top_band)] = R["shoulders"]
    under = rest & (z <= top_band) & (z > st["chest"] - 0.02 * H) & (np.abs(x) > 0.75 * half)
    region[under] = R["under the arms"]
    rest = trunk & (region < 0)
    region[rest & (z > st["waist"])] = R["chest and back"]
    region[rest & (z <= st["waist"]) & (z > crotch_z + 0.03 * H)] = R["abdomen and hips"]
    region[rest & (z <= crotch_z + 0.03 * H)] = R["crotch and inner thighs"]

    axis = np.zeros(len(points))
    for s in (0, 1):
        sel = arm & (side == s)
        if sel.any():
            axis[sel] = arm_axis_x(s, z[sel])
    elbow_z = joint["elbow_joint"][side, 2]
    region[arm & (z > armpit_z)] = R["shoulders"]
    region[arm & (z <= armpit_z) & (z > armpit_z - 0.1 * H) & (np.abs(x) < axis)] = R["under the arms"]
    rest = arm & (region < 0)
    region[rest & (z > elbow_z)] = R["upper arms"]
    region[rest & (z <= elbow_z)] = R["forearms and hands"]

    for s in (0, 1):
        sel = leg & (side == s)
        if sel.any():
            axis[sel] = leg_axis_x(s, np.maximum(z[sel], joint["ankle_joint"][s, 2]))
    ankle_z = joint["ankle_joint"][side, 2]
    region[leg & (z <= ankle_z)] = R["feet"]
    region[leg & (z > ankle_z) & (z >= crotch_z - 0.12 * H) & (np.abs(x) < axis)] = R["crotch and inner thighs"]
    region[leg & (region < 0)] = R["legs"]
    return region


def cut_loop(mesh_v, mesh_t, point, normal):
    """The closed loop of the mesh's section by the plane (point, normal) that encloses the
    point, as an (n, 3) polyline (first point repeated at the end); None if none does."""
    n = np.asarray(normal, float)
    n /= np.linalg.norm(n)
    p0 = np.asarray(point, float)
    near = np.linalg.norm(mesh_v - p0, axis=1) < 800
    side = (mesh_v - p0) @ n
    side[side == 0] = 1e-12
    tri = mesh_t[near[mesh_t].all(axis=1)]
    s = side[tri] > 0
    crossing = tri[(s.sum(axis=1) == 1) | (s.sum(axis=1) == 2)]
    if len(crossing) == 0:
        return None
    neighbours = {}
    for a, b, c in crossing:
        keys = [tuple(sorted(e)) for e in ((a, b), (b, c), (c, a)) if (side[e[0]] > 0) != (side[e[1]] > 0)]
        k0, k1 = keys
        neighbours.setdefault(k0, []).append(k1)
        neighbours.setdefault(k1, []).append(k0)

    def at(key):
        i, j = key
        t = side[i] / (side[i] - side[j])
        return mesh_v[i] + t * (mesh_v[j] - mesh_v[i])

    e1 = np.cross(n, [1.0, 0, 0] if abs(n[0]) < 0.9 else [0, 1.0, 0])
    e1 /= np.linalg.norm(e1)
    e2 = np.cross(n, e1)
    unvisited = set(neighbours)
    while unvisited:
        start = unvisited.pop()
        loop, prev, cur = [start], None, start
        while True:
            nxt = [k for k in neighbours[cur] if k != prev]
            if not nxt or nxt[0] == start:
                break
            prev, cur = cur, nxt[0]
            if cur not in unvisited:
                break
            unvisited.discard(cur)
            loop.append(cur)
        pts = np.array([at(k) for k in loop])
        if len(pts) < 3:
            continue
        q = np.stack([(pts - p0) @ e1, (pts - p0) @ e2], axis=1)
        q2 = np.roll(q, -1, axis=0)
        crosses = (q[:, 1] > 0) != (q2[:, 1] > 0)
        xs = q[:, 0] + (0 - q[:, 1]) * (q2[:, 0] - q[:, 0]) / np.where(q2[:, 1] == q[:, 1], 1e-12, q2[:, 1] - q[:, 1])
        if np.sum(crosses & (xs > 0)) % 2 == 1:
            return np.vstack([pts, pts[:1]])
    return None


def resample(polyline, step=1.0):
    """Points every `step` mm along a polyline."""
    seg = np.diff(polyline, axis=0)
    length = np.linalg.norm(seg, axis=1)
    out = []
    for a, d, l in zip(polyline[:-1], seg, length):
        k = max(1, int(np.ceil(l / step)))
        out.append(a + np.outer(np.arange(k) / k, d))
    return np.vstack(out)


def section_loops(meta, v, t):
    """Each girth section of the truth, as its loop on the true surface resampled every mm
    (None where the plane misses the body)."""
    loops = {}
    for key, value in meta["truth"].items():
        section = value.get("section")
        if section:
            loop = cut_loop(v, t, section["point"], section["normal"])
            loops[key] = None if loop is None else resample(loop)
    return loops


def score(subject_ply, meta, mesh_ply=None, cloud_ply=None, sim_dir=None, archive=None):
    """The body's coverage figures: overall and per region (the share of the true surface,
    soles excluded, within 5 mm of the processed mesh), per girth section (the share of its
    perimeter within 5 mm), the cloud's points more than 5 mm off the surface, and, given
    the sim's truth peaks (sim_dir, a `sim scan --truth` output) and the archive, the share the
    cabinet's optics and the extractor reach (within 5 mm of a truth peak the extractor
    found). Returns (figures, samples, seen, optics) with the samples (points, normals,
    region) and each one's seen flags (processed, optics), for pictures."""
    truth = o3d.io.read_triangle_mesh(subject_ply)
    v, t = np.asarray(truth.vertices), np.asarray(truth.triangles)
    points, tri, normals = surface_samples(truth)
    part = triangle_parts(meta, len(t))[tri]
    region = classify(meta, points, part)
    out = {"samples": int(len(points))}
    seen = np.zeros(len(points), bool)
    optics = np.zeros(len(points), bool)
    mesh_distance = None
    loops = section_loops(meta, v, t)  # each girth's loop on the true surface
    if mesh_ply and os.path.exists(mesh_ply):
        mesh = o3d.io.read_triangle_mesh(mesh_ply)
        mesh_distance = Distance(mesh)
        seen = mesh_distance(points) < SEEN_MM
        out["coverage_pct"] = round(100 * float(seen.mean()), 1)
        out["regions"] = {}
        for i, name in enumerate(REGIONS):
            sel = region == i
            out["regions"][name] = round(100 * float(seen[sel].mean()), 1) if sel.any() else None
        out["sections"] = {key: None if along is None else
                           round(100 * float(np.mean(mesh_distance(along) < SEEN_MM)), 1)
                           for key, along in loops.items()}
    if sim_dir:
        # What the optics and the extractor reach: truth peaks on the subject with a peak of
        # the archive within 1 px of their row (scripts/score-reconstruction's matching).
        with open(os.path.join(sim_dir, "sweep.json")) as f:
            cameras = json.load(f)["cameras"]
        truth_peaks = SCORE.read_truth(sim_dir, cameras)
        truth_peaks = truth_peaks[truth_peaks[:, 9] == 1]
        found = SCORE.read_mscan_peaks(archive)
        near = SCORE.nearest_in_column(
            SCORE.column_key(truth_peaks[:, 0], truth_peaks[:, 1], truth_peaks[:, 2]), truth_peaks[:, 3],
            SCORE.column_key(found[:, 0], found[:, 1], found[:, 2]), found[:, 3], 1.0)
        lit = o3d.geometry.PointCloud(o3d.utility.Vector3dVector(truth_peaks[near >= 0, 6:9]))
        query = o3d.geometry.PointCloud(o3d.utility.Vector3dVector(points))
        optics = np.asarray(query.compute_point_cloud_distance(lit)) < SEEN_MM
        out["optics_pct"] = round(100 * float(optics.mean()), 1)
        out["optics_regions"] = {name: round(100 * float(optics[region == i].mean()), 1)
                                 if (region == i).any() else None for i, name in enumerate(REGIONS)}
        out["optics_sections"] = {
            key: None if along is None else round(100 * float(np.mean(np.asarray(
                o3d.geometry.PointCloud(o3d.utility.Vector3dVector(along))
                .compute_point_cloud_distance(lit)) < SEEN_MM)), 1)
            for key, along in loops.items()}
    if cloud_ply and os.path.exists(cloud_ply):
        cloud_points = read_cloud_xyz(cloud_ply)
        out["points"] = int(len(cloud_points))
        d = Distance(truth)(cloud_points)
        out["points_beyond_5mm"] = int(np.sum(d > 5))
        out["points_beyond_20mm"] = int(np.sum(d > 20))
    return out, (points, normals, region), seen, optics


def unseen_picture(samples, seen, png, scale=0.25):
    """Front and back views of the true surface side by side (a 2 m body 500 px tall), seen
    parts shaded grey by slope, unseen parts red."""
    points, normals, _ = samples
    width, height = int(1700 * scale), int(2150 * scale)
    panels = []
    for back in (False, True):
        u = -points[:, 0] if back else points[:, 0]  # the camera's right is +x
        depth = points[:, 1] if back else -points[:, 1]
        facing = normals[:, 1] if back else -normals[:, 1]
        image = np.full((height, width, 3), 255, np.uint8)
        px = np.round(u * scale + width / 2).astype(int)
        py = np.round((2120 - points[:, 2]) * scale).astype(int)
        ok = (px >= 0) & (px < width) & (py >= 0) & (py < height) & (facing > 0)
        order = np.argsort(depth[ok])  # depth is nearness: far first, the near drawn last
        shade = (60 + 180 * np.clip(facing[ok], 0, 1))[order]
        colour = np.stack([shade, shade, shade], axis=1)
        red = ~seen[ok][order]
        colour[red] = np.stack([np.full(red.sum(), 230.0), 0.25 * shade[red], 0.25 * shade[red]], axis=1)
        image[py[ok][order], px[ok][order]] = colour.astype(np.uint8)
        panels.append(image)
    sheet = np.concatenate(panels, axis=1)
    o3d.io.write_image(png, o3d.geometry.Image(np.ascontiguousarray(sheet)))


def load_meta(path):
    with open(path) as f:
        return json.load(f)
