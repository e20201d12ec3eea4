#!/usr/bin/env python3
"""The Embree peer of `prt-gpu bake` (issue 29): shadowed PRT as the tutorial in
references/gentle-introduction-to-prt.md computes it -- one stratified sample set on the sphere
shared by every vertex, a shadow ray from each vertex along every sample above its horizon, the
visible cosine projected on 4 bands of SH -- in numpy, its rays cast by Embree (embreex). It is
timed on the same mesh, in the same run, alternating with `prt-gpu bake` of that mesh, and the
two rays/s are printed side by side with their ratio (the machine is shared: compare ratios, not
absolute figures between runs).

    pip install numpy embreex
    cargo build --release
    benches/peers/embree_peer.py [MESH.ply|MESH.ply.gz] [--samples 1024] [--repeats 3]

Only the rays cast count: the peer casts the samples above each vertex's horizon (about half of
its sphere set), prt-gpu its cosine-distributed hemisphere set (all of them).
"""

import argparse
import gzip
import math
import re
import subprocess
import sys
import time
from pathlib import Path

import numpy as np
from embreex import rtcore_scene
from embreex.mesh_construction import TriangleMesh

ROOT = Path(__file__).resolve().parents[2]


def read_ply(path):
    """Vertices and triangles of an ASCII or binary little-endian PLY (float x y z first, faces
    as a list of indices)."""
    raw = gzip.open(path, "rb").read() if str(path).endswith(".gz") else open(path, "rb").read()
    end = raw.index(b"end_header") + len(b"end_header")
    end = raw.index(b"\n", end) + 1
    header = raw[:end].decode("ascii").splitlines()
    fmt = next(line.split()[1] for line in header if line.startswith("format"))
    counts, properties, element = {}, {}, None
    for line in header:
        words = line.split()
        if words[:1] == ["element"]:
            element = words[1]
            counts[element] = int(words[2])
            properties[element] = []
        elif words[:1] == ["property"]:
            properties[element].append(words[1:])
    body = raw[end:]
    nv, nf = counts["vertex"], counts["face"]
    if fmt == "ascii":
        lines = body.decode("ascii").split("\n")
        vertices = np.array([l.split()[:3] for l in lines[:nv]], dtype=np.float32)
        faces = [l.split() for l in lines[nv:nv + nf]]
        triangles = np.array([f[1:4] for f in faces if f[0] == "3"], dtype=np.int32)
        return vertices, triangles
    if fmt != "binary_little_endian":
        sys.exit(f"{path}: PLY format {fmt} (ascii or binary_little_endian)")
    sizes = {"float": "f4", "float32": "f4", "double": "f8", "uchar": "u1", "uint8": "u1",
             "int": "i4", "int32": "i4", "uint": "u4", "uint32": "u4", "short": "i2",
             "ushort": "u2"}
    vertex_type = np.dtype([(p[1], "<" + sizes[p[0]]) for p in properties["vertex"]])
    table = np.frombuffer(body, vertex_type, nv)
    vertices = np.stack([table["x"], table["y"], table["z"]], 1).astype(np.float32)
    count_type, index_type = (sizes[t] for t in properties["face"][0][1:3])
    face_type = np.dtype([("n", "<" + count_type), ("i", "<" + index_type, 3)])
    faces = np.frombuffer(body, face_type, nf, nv * vertex_type.itemsize)
    if not (faces["n"] == 3).all():
        sys.exit(f"{path}: only triangle faces are read")
    return vertices, faces["i"].astype(np.int32)


def vertex_normals(vertices, triangles):
    """Area-weighted vertex normals."""
    a, b, c = (vertices[triangles[:, i]] for i in range(3))
    face = np.cross(b - a, c - a)
    normals = np.zeros_like(vertices)
    for i in range(3):
        np.add.at(normals, triangles[:, i], face)
    length = np.linalg.norm(normals, axis=1, keepdims=True)
    return normals / np.maximum(length, 1e-30)


def stratified_sphere(n, rng):
    """The tutorial's stratified sampling: sqrt(n) x sqrt(n) cells of the unit square, a random
    point in each, mapped to the sphere (theta = 2 acos(sqrt(1 - x)), phi = 2 pi y)."""
    side = int(math.isqrt(n))
    i, j = np.meshgrid(np.arange(side), np.arange(side), indexing="ij")
    x = (i.ravel() + rng.random(side * side)) / side
    y = (j.ravel() + rng.random(side * side)) / side
    theta, phi = 2 * np.arccos(np.sqrt(1 - x)), 2 * np.pi * y
    return np.stack([np.sin(theta) * np.cos(phi), np.sin(theta) * np.sin(phi), np.cos(theta)], 1)


def sh4(d):
    """Real orthonormal SH of bands 0-3 at unit directions d, k = l(l+1)+m."""
    x, y, z = d[:, 0], d[:, 1], d[:, 2]
    return np.stack([
        0.282095 * np.ones_like(x),
        0.488603 * y, 0.488603 * z, 0.488603 * x,
        1.092548 * x * y, 1.092548 * y * z, 0.315392 * (3 * z * z - 1),
        1.092548 * x * z, 0.546274 * (x * x - y * y),
        0.590044 * y * (3 * x * x - y * y), 2.890611 * x * y * z,
        0.457046 * y * (5 * z * z - 1), 0.373176 * z * (5 * z * z - 3),
        0.457046 * x * (5 * z * z - 1), 1.445306 * z * (x * x - y * y),
        0.590044 * x * (x * x - 3 * y * y),
    ], 1).astype(np.float32)


def embree_bake(vertices, triangles, samples, chunk=1024):
    """Shadowed transfer at every vertex: the seconds of its rays and projection (as prt-gpu's
    "rays in ... s" counts its direct pass: the BVH, normals and sample set built before), the
    seconds of those inside Embree's ray queries, and the rays it cast."""
    scene = rtcore_scene.EmbreeScene()
    TriangleMesh(scene, vertices, triangles)
    normals = vertex_normals(vertices, triangles)
    directions = stratified_sphere(samples, np.random.default_rng(1)).astype(np.float32)
    basis = sh4(directions)
    extent = float(np.linalg.norm(vertices.max(0) - vertices.min(0)))
    # Embree builds its BVH at the first query: one ray, before the clock starts.
    scene.run(vertices[:1], directions[:1], query="OCCLUDED")
    started = time.perf_counter()
    transfer = np.zeros((len(vertices), 16), np.float32)
    rays, in_embree = 0, 0.0
    for first in range(0, len(vertices), chunk):
        p, n = vertices[first:first + chunk], normals[first:first + chunk]
        cosine = n @ directions.T
        above = cosine > 0
        vertex, sample = np.nonzero(above)
        origins = p[vertex] + 1e-4 * extent * n[vertex]
        casting = time.perf_counter()
        occluded = scene.run(origins.astype(np.float32), directions[sample], query="OCCLUDED")
        in_embree += time.perf_counter() - casting
        visible = np.zeros(above.shape, np.float32)
        visible[vertex, sample] = (occluded == -1) * cosine[vertex, sample]
        transfer[first:first + chunk] = visible @ basis * (4 * np.pi / len(directions) / np.pi)
        rays += len(vertex)
    return time.perf_counter() - started, in_embree, rays


def prt_gpu_bake(binary, mesh, samples):
    """`prt-gpu bake` of `mesh` on the CPU backend: its rays/s as it reports them."""
    out = subprocess.run(
        [str(binary), "bake", str(mesh), "--samples", str(samples), "--device", "cpu",
         "-o", "/tmp/embree-peer-prt-gpu.glb"],
        capture_output=True, text=True, check=True)
    said = out.stdout + out.stderr
    found = re.search(r"(\d+) rays in ([\d.]+) s \(([\d.]+) M rays/s\)", said)
    if not found:
        sys.exit(f"no rays/s in prt-gpu's output:\n{said}")
    return float(found.group(3)) * 1e6


def main():
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    default = ROOT.parent / "shared/data/meshes/dragon_vrip_res3.ply.gz"
    parser.add_argument("mesh", nargs="?", default=default, type=Path)
    parser.add_argument("--samples", type=int, default=1024)
    parser.add_argument("--repeats", type=int, default=3)
    parser.add_argument("--prt-gpu", type=Path, default=ROOT / "target/release/prt-gpu")
    args = parser.parse_args()
    vertices, triangles = read_ply(args.mesh)
    mesh = args.mesh
    if str(mesh).endswith(".gz"):
        mesh = Path("/tmp/embree-peer-mesh.ply")
        mesh.write_bytes(gzip.open(args.mesh, "rb").read())
    print(f"{args.mesh.name}: {len(vertices)} vertices, {len(triangles)} triangles, "
          f"{args.samples} samples a vertex, {args.repeats} rounds alternating")
    peer, ours = [], []
    for round in range(args.repeats):
        seconds, in_embree, rays = embree_bake(vertices, triangles, args.samples)
        peer.append(rays / seconds)
        ours.append(prt_gpu_bake(args.prt_gpu, mesh, args.samples))
        print(f"round {round + 1}: embree peer {peer[-1] / 1e6:.2f} M rays/s ({rays} rays in "
              f"{seconds:.2f} s, {in_embree:.2f} s of it in Embree: {rays / in_embree / 1e6:.2f} "
              f"M rays/s there), prt-gpu {ours[-1] / 1e6:.2f} M rays/s")
    peer_median, ours_median = float(np.median(peer)), float(np.median(ours))
    print(f"median: embree peer {peer_median / 1e6:.2f} M rays/s, prt-gpu "
          f"{ours_median / 1e6:.2f} M rays/s: {ours_median / peer_median:.1f}x")


if __name__ == "__main__":
    main()
