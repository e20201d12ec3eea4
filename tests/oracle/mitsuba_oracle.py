#!/usr/bin/env python3
"""Exit radiance by path tracing with Mitsuba 3: the independent oracle of the accuracy tests.

Usage: mitsuba_oracle.py JOB_DIR

JOB_DIR/job.json says what to render; the arrays it names are little-endian raw files in
JOB_DIR (float32 unless said otherwise):
    {
      "vertices": V, "faces": F, "points": N,
      "positions": "positions.f32",   # V x 3
      "normals": "normals.f32",       # V x 3, the shading normals the baker used
      "albedo": "albedo.f32",         # V x 3, linear RGB, interpolated over each face
      "triangles": "triangles.u32",   # F x 3
      "query_points": "points.f32",   # N x 3, points on the surface
      "query_normals": "qnormals.f32",# N x 3, their shading normals
      "query_faces": "qfaces.u32",    # N, a face each point lies on
      "light": {"type": "point", "position": [x, y, z], "intensity": I}
             | {"type": "spot", "position": [...], "direction": [...],
                "half_angle_degrees": A, "intensity": I}
             | {"type": "sh", "bands": B, "coefficients": [[r, g, b], ...]},
      "query": "exit",                # exit radiance at surface points (the default), or
             "irradiance",            # irradiance at free points for the query normals
      "bounces": K,                   # exit: 0 is direct light only
      "reflections": R,               # irradiance: surface reflections a path may have
                                      # (0: the sky alone, the scene a black occluder)
      "samples": S,                   # paths per point
      "seed": 1,
      "medium": {"sigma_a": [r, g, b],   # optional (exit only): the mesh is the boundary of
                 "sigma_s": [r, g, b],   # a homogeneous medium (isotropic phase function,
                 "ior": eta}             # per scene unit) behind a smooth dielectric; the
                                         # volumetric path tracer follows its light
    }

Writes JOB_DIR/radiance.f32 (N x 3, the mean) and JOB_DIR/stderr.f32 (N x 3, the standard
error of that mean over the S paths), and prints one JSON line: the variant, the seconds.

Nothing here comes from prt-gpu: the SH basis below is written from its definition (real,
orthonormal, Condon-Shortley phase, index l(l+1)+m), so that a sky given by coefficients is
the same function of direction for both.
"""

import json
import math
import os
import sys
import time

import numpy as np


def pick_variant():
    """llvm_ad_rgb (vectorised) where Dr.Jit finds libLLVM, else scalar_rgb."""
    import mitsuba as mi

    for variant in ("llvm_ad_rgb", "scalar_rgb"):
        if variant in mi.variants():
            try:
                mi.set_variant(variant)
                return mi, variant
            except Exception:  # Dr.Jit found no LLVM
                continue
    raise SystemExit("mitsuba_oracle: no usable Mitsuba variant")


def read(job_dir, name, dtype, shape):
    data = np.fromfile(os.path.join(job_dir, name), dtype=dtype)
    return data.reshape(shape)


def sh_basis(bands, directions):
    """Real orthonormal SH, Condon-Shortley phase, (n, bands^2), from the definition:
    y_lm = sqrt(2) K_lm P_l^m(cos t) cos(m p) for m > 0, sqrt(2) K P_l^|m| sin(|m| p) for
    m < 0, K P_l^0 for m = 0, with P_l^m by the standard upward recurrences in float64."""
    x, y, z = directions[:, 0], directions[:, 1], directions[:, 2]
    # prt-gpu's stated convention (its files' metadata): theta from +Z, phi from +X
    # towards +Y, in world space.
    cos_t = np.clip(z, -1.0, 1.0)
    sin_t = np.sqrt(np.maximum(0.0, 1.0 - cos_t * cos_t))
    phi = np.arctan2(y, x)
    out = np.zeros((directions.shape[0], bands * bands))
    for m in range(bands):
        # P_m^m = (-1)^m (2m-1)!! sin^m
        pmm = np.ones_like(cos_t)
        for i in range(1, m + 1):
            pmm = -pmm * (2 * i - 1) * sin_t
        p_prev, p = None, pmm
        for l in range(m, bands):
            if l == m:
                p_l = pmm
            elif l == m + 1:
                p_l = cos_t * (2 * m + 1) * pmm
            else:
                p_l = (cos_t * (2 * l - 1) * p - (l + m - 1) * p_prev) / (l - m)
            if l > m:
                p_prev, p = p, p_l
            k = math.sqrt((2 * l + 1) / (4 * math.pi) * math.factorial(l - m) / math.factorial(l + m))
            if m == 0:
                out[:, l * (l + 1)] = k * p_l
            else:
                out[:, l * (l + 1) + m] = math.sqrt(2) * k * p_l * np.cos(m * phi)
                out[:, l * (l + 1) - m] = math.sqrt(2) * k * p_l * np.sin(m * phi)
    return out


def sh_envmap(mi, bands, coefficients, width=1024):
    """A lat-long map of the band-limited sky sum_k c_k y_k(w), laid out as Mitsuba's envmap
    reads it: pixel (u, v) looks along the direction Mitsuba's own envmap plugin gives it,
    found by asking the plugin (no convention is assumed here)."""
    height = width // 2
    u = (np.arange(width) + 0.5) / width
    v = (np.arange(height) + 0.5) / height
    uu, vv = np.meshgrid(u, v)
    # Mitsuba's envmap: phi = 2 pi u, theta = pi v, d = (sin phi sin theta, cos theta,
    # -cos phi sin theta) in its local frame; checked below against the plugin itself.
    phi, theta = 2 * math.pi * uu, math.pi * vv
    d = np.stack(
        [np.sin(phi) * np.sin(theta), np.cos(theta), -np.cos(phi) * np.sin(theta)], axis=-1
    ).reshape(-1, 3)
    c = np.asarray(coefficients, dtype=np.float64).reshape(bands * bands, 3)
    radiance = sh_basis(bands, d) @ c
    image = radiance.reshape(height, width, 3).astype(np.float32)
    return image, d, radiance


def check_envmap_convention(mi, emitter, directions, radiance):
    """The envmap plugin's radiance along a few directions must be the sky's there: a check
    that the layout above is the plugin's, so a wrong convention fails loudly here."""
    pick = np.linspace(0, directions.shape[0] - 1, 64).astype(int)
    si = mi.SurfaceInteraction3f()
    worst = 0.0
    for i in pick:
        si.wi = mi.Vector3f(*[float(x) for x in -directions[i]])
        value = np.array(emitter.eval(si)).reshape(-1)[:3]
        worst = max(worst, float(np.max(np.abs(value - radiance[i]))))
    scale = float(np.max(np.abs(radiance))) + 1e-12
    if worst > 0.05 * scale:
        raise SystemExit(f"mitsuba_oracle: envmap layout disagrees with the plugin ({worst})")


def light_dict(mi, light):
    kind = light["type"]
    intensity = {"type": "rgb", "value": [float(light.get("intensity", 1.0))] * 3}
    if kind == "point":
        return {"type": "point", "position": light["position"], "intensity": intensity}
    if kind == "spot":
        origin = np.array(light["position"], dtype=float)
        target = origin + np.array(light["direction"], dtype=float)
        up = [0, 1, 0] if abs(light["direction"][1]) < 0.9 else [1, 0, 0]
        angle = float(light["half_angle_degrees"])
        return {
            "type": "spot",
            "to_world": mi.ScalarTransform4f().look_at(
                origin=origin.tolist(), target=target.tolist(), up=up
            ),
            "intensity": intensity,
            "cutoff_angle": angle,
            # A hard edge as the baker's: the smooth fall-off squeezed into a hair.
            "beam_width": angle * (1.0 - 1e-6),
        }
    raise SystemExit(f"mitsuba_oracle: unknown light type {kind!r}")


def build_scene(mi, job, job_dir):
    V, F = job["vertices"], job["faces"]
    positions = read(job_dir, job["positions"], "<f4", (V, 3))
    normals = read(job_dir, job["normals"], "<f4", (V, 3))
    albedo = read(job_dir, job["albedo"], "<f4", (V, 3))
    triangles = read(job_dir, job["triangles"], "<u4", (F, 3))
    props = mi.Properties()
    props["face_normals"] = False
    medium = job.get("medium")
    if medium:
        props["bsdf"] = mi.load_dict(
            {"type": "dielectric", "int_ior": float(medium["ior"]), "ext_ior": 1.0}
        )
        sigma_t = [a + s for a, s in zip(medium["sigma_a"], medium["sigma_s"])]
        albedo_v = [s / t for s, t in zip(medium["sigma_s"], sigma_t)]
        # RGB values are read as reflectances (at most 1): sigma_t as a fraction of `scale`.
        scale = max(sigma_t)
        props["interior"] = mi.load_dict({
            "type": "homogeneous",
            "sigma_t": {"type": "rgb", "value": [t / scale for t in sigma_t]},
            "scale": scale,
            "albedo": {"type": "rgb", "value": albedo_v},
            "phase": {"type": "isotropic"},
        })
    else:
        props["bsdf"] = mi.load_dict(
            {"type": "diffuse", "reflectance": {"type": "mesh_attribute", "name": "vertex_color"}}
        )
    mesh = mi.Mesh("scene", V, F, props=props, has_vertex_normals=True)
    params = mi.traverse(mesh)
    # The buffers' own types: Dr.Jit arrays in the LLVM variant, dynamic arrays in scalar.
    as_buffer = lambda key, values: type(params[key])(values.ravel())
    params["vertex_positions"] = as_buffer("vertex_positions", positions.astype(np.float32))
    params["vertex_normals"] = as_buffer("vertex_normals", normals.astype(np.float32))
    params["faces"] = as_buffer("faces", triangles.astype(np.uint32))
    params.update()
    mesh.add_attribute(
        "vertex_color", 3, type(params["vertex_positions"])(albedo.astype(np.float32).ravel())
    )
    # Embree's fast mode lets rays through the edges between triangles, and in the vectorised
    # variant it gave wrong shadows to whole packets of 4 rays here; robust mode does not.
    scene = {"type": "scene", "mesh": mesh, "embree_use_robust_intersections": True}
    light = job["light"]
    if light["type"] == "sh":
        image, d, radiance = sh_envmap(mi, light["bands"], light["coefficients"])
        # A band-limited sky may dip below zero; the envmap plugin takes signed values.
        scene["sky"] = {"type": "envmap", "bitmap": mi.Bitmap(image)}
        loaded = mi.load_dict(scene)
        check_envmap_convention(mi, loaded.environment(), d, radiance)
        return loaded, positions, triangles
    scene["light"] = light_dict(mi, light)
    return mi.load_dict(scene), positions, triangles


def query_rays(job, job_dir, positions, triangles, extent):
    """Per point, a ray from just above it (point + n delta) straight down at it, nudged a
    hair towards its face's centroid so that it lands on that face."""
    N = job["points"]
    points = read(job_dir, job["query_points"], "<f4", (N, 3)).astype(np.float64)
    normals = read(job_dir, job["query_normals"], "<f4", (N, 3)).astype(np.float64)
    faces = read(job_dir, job["query_faces"], "<u4", (N,))
    centroids = positions[triangles[faces]].astype(np.float64).mean(axis=1)
    delta = 1e-4 * extent
    target = points + 1e-3 * (centroids - points)
    origin = points + normals * delta
    direction = target - origin
    direction /= np.linalg.norm(direction, axis=1, keepdims=True)
    return origin, direction


def render(mi, variant, scene, origin, direction, bounces, samples, seed, medium=False):
    """Mean and standard error of the path integrator's radiance along each ray, `samples`
    paths per ray (max_depth 2 + bounces: depth 2 is direct light only, no Russian roulette
    within these depths). In a medium, the volumetric path tracer, `bounces` scattering and
    surface events at most (Russian roulette after 64, unbiased)."""
    integrator = mi.load_dict(
        {"type": "volpath", "max_depth": bounces, "rr_depth": 64, "hide_emitters": True}
        if medium
        else {"type": "path", "max_depth": 2 + bounces, "rr_depth": 1000, "hide_emitters": True}
    )
    return mean_and_error(
        mi, variant, scene, integrator, origin.shape[0], samples, seed,
        lambda start, stop: (
            np.repeat(origin[start:stop], samples, axis=0),
            np.repeat(direction[start:stop], samples, axis=0),
        ),
        1.0,
    )


def irradiance(mi, variant, scene, points, normals, reflections, samples, seed):
    """Irradiance at free points for surfaces of the given normals: pi times the mean radiance
    arriving along cosine-distributed directions (Malley's method, drawn here with numpy),
    the sky seen directly (emitters shown) and through up to `reflections` diffuse
    reflections (max_depth 1 + reflections, no Russian roulette)."""
    integrator = mi.load_dict(
        {"type": "path", "max_depth": 1 + reflections, "rr_depth": 1000, "hide_emitters": False}
    )
    rng = np.random.default_rng(seed)
    return mean_and_error(
        mi, variant, scene, integrator, points.shape[0], samples, seed,
        lambda start, stop: (
            np.repeat(points[start:stop], samples, axis=0),
            cosine_directions(rng, np.repeat(normals[start:stop], samples, axis=0)),
        ),
        math.pi,
    )


def mean_and_error(mi, variant, scene, integrator, N, samples, seed, rays, scale):
    """Mean and standard error over `samples` paths of each of N queries of `scale` times the
    integrator's radiance along the rays `rays(start, stop)` gives for queries start..stop."""
    total = np.zeros((N, 3))
    squares = np.zeros((N, 3))
    # Batches of about 2M paths keep Dr.Jit's memory bounded.
    per_batch = max(1, 2_000_000 // max(1, samples))
    for start in range(0, N, per_batch):
        stop = min(N, start + per_batch)
        n = stop - start
        o, d = rays(start, stop)
        if variant.startswith("scalar"):
            values = scalar_paths(mi, integrator, scene, o, d, seed + start)
        else:
            sampler = mi.load_dict({"type": "independent"})
            sampler.seed(seed + start, n * samples)
            ray = mi.Ray3f(
                mi.Point3f(*[mi.Float(o[:, i].astype(np.float32)) for i in range(3)]),
                mi.Vector3f(*[mi.Float(d[:, i].astype(np.float32)) for i in range(3)]),
            )
            color, _, _ = integrator.sample(scene, sampler, ray)
            values = np.stack([np.array(color[i], dtype=np.float64) for i in range(3)], axis=1)
        values = scale * values.reshape(n, samples, 3)
        total[start:stop] = values.sum(axis=1)
        squares[start:stop] = (values * values).sum(axis=1)
    mean = total / samples
    variance = np.maximum(0.0, squares / samples - mean * mean) * samples / max(1, samples - 1)
    return mean, np.sqrt(variance / samples)


def cosine_directions(rng, normals):
    """A cosine-distributed direction about each unit normal: a uniform point of the unit
    disk lifted onto the hemisphere, in a frame built around the normal."""
    u1, u2 = rng.random(normals.shape[0]), rng.random(normals.shape[0])
    r, phi = np.sqrt(u1), 2 * math.pi * u2
    local = np.stack([r * np.cos(phi), r * np.sin(phi), np.sqrt(np.maximum(0.0, 1.0 - u1))], 1)
    helper = np.where(np.abs(normals[:, :1]) > 0.9, [[0.0, 1.0, 0.0]], [[1.0, 0.0, 0.0]])
    tangent = np.cross(helper, normals)
    tangent /= np.linalg.norm(tangent, axis=1, keepdims=True)
    bitangent = np.cross(normals, tangent)
    return local[:, :1] * tangent + local[:, 1:2] * bitangent + local[:, 2:] * normals


def scalar_paths(mi, integrator, scene, o, d, seed):
    sampler = mi.load_dict({"type": "independent"})
    sampler.seed(seed, 1)
    out = np.zeros((o.shape[0], 3))
    for i in range(o.shape[0]):
        ray = mi.Ray3f(mi.Point3f(*o[i]), mi.Vector3f(*d[i]))
        color, _, _ = integrator.sample(scene, sampler, ray)
        out[i] = [color[0], color[1], color[2]]
        sampler.advance()
    return out


def main():
    job_dir = sys.argv[1]
    with open(os.path.join(job_dir, "job.json")) as f:
        job = json.load(f)
    started = time.time()
    mi, variant = pick_variant()
    if variant.startswith("scalar") and job["points"] * job["samples"] > 200_000:
        raise SystemExit(
            "mitsuba_oracle: only the scalar variant loads (Dr.Jit found no libLLVM: install "
            "Debian's libllvm19 or set DRJIT_LIBLLVM_PATH); it is too slow for this job"
        )
    scene, positions, triangles = build_scene(mi, job, job_dir)
    if job.get("query", "exit") == "irradiance":
        N = job["points"]
        points = read(job_dir, job["query_points"], "<f4", (N, 3)).astype(np.float64)
        normals = read(job_dir, job["query_normals"], "<f4", (N, 3)).astype(np.float64)
        normals /= np.linalg.norm(normals, axis=1, keepdims=True)
        mean, error = irradiance(
            mi, variant, scene, points, normals, job["reflections"], job["samples"],
            job.get("seed", 1),
        )
    else:
        extent = float(np.max(positions.max(axis=0) - positions.min(axis=0)))
        origin, direction = query_rays(job, job_dir, positions, triangles, extent)
        mean, error = render(
            mi, variant, scene, origin, direction, job["bounces"], job["samples"],
            job.get("seed", 1), medium=bool(job.get("medium")),
        )
    mean.astype("<f4").tofile(os.path.join(job_dir, "radiance.f32"))
    error.astype("<f4").tofile(os.path.join(job_dir, "stderr.f32"))
    print(json.dumps({"variant": variant, "mitsuba": mi.__version__,
                      "seconds": time.time() - started}))


if __name__ == "__main__":
    main()
