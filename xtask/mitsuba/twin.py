#!/usr/bin/env python3
"""A Lucent scene file (TOML) as a Mitsuba 3 scene, and Mitsuba's render of it.

Shared by heavy.py and seed.py, so each twin reads the very TOML Lucent
renders and the two cannot drift apart. Run with the Mitsuba peer's venv
(../shared/peers/mitsuba/requirements.txt; `llvm_ad_rgb` also needs libllvm).

  twin.py render SCENE.toml --spp N --seed S --out STEM [--variant llvm_ad_rgb]
      STEM.exr (linear) and STEM.png; prints one JSON line with render_s,
      timed after a 1-spp warm-up (LLVM compiles its kernels there)
  twin.py dict SCENE.toml     the Mitsuba scene dictionary, for reading

Only what both renderers implement identically is mapped; anything else is
an error naming the key, never a silent approximation:

- `[render]`: width, height, max_depth, rr_depth (Mitsuba's meanings are
  Lucent's), integrator "path"; clamp_indirect and free_delta_bounces must
  be 0 (they bias). Box pixel filter, independent sampler.
- `[camera]`: the orbit rig (center, radius, theta_deg, phi_deg,
  fov_y_deg), all given.
- `[environment]`: `background` becomes a `constant` emitter (Lucent
  samples its constant background as a light too); `map` is not mapped.
- `[[lights]]`: directional (Mitsuba `directional`, irradiance =
  intensity) and point lights.
- `[materials]`: the path tracer's reading (docs/scene-format.md,
  "Materials in the path tracer"): weights clamped to 0..1 and scaled
  down together when kd + kr + kt exceeds 1 in some channel; kd is a
  two-sided Lambertian (`twosided` `diffuse`, the texture as a bilinear
  `bitmap`, sRGB decoded, when kd is 1), kr a two-sided conductor with
  Fresnel 1 (`conductor`, or GGX `roughconductor` with alpha =
  roughness^2 when roughness > 0; Mitsuba's GGX masking is the separable
  Smith term, Lucent's the height-correlated one, a few per cent apart at
  grazing angles), kt a smooth `dielectric` of that reflectance and
  transmittance with int_ior = ior. Lucent picks a lobe with probability
  proportional to the mean of its weight and weighs the sample by the
  whole mixture (one-sample MIS); nested `blendbsdf`s with those
  probabilities as weights, and each lobe scaled by the inverse of its
  probability, are the same estimator in Mitsuba 3.9 for smooth lobes.
  A delta lobe (smooth mirror, dielectric) mixed with a smooth one is not:
  Mitsuba 3.9's blendbsdf (since its PR 1681) weighs a delta sample by the
  mixture's value over its density, adding the smooth lobes' value and
  density in the delta direction to the delta's reflectance and selection
  probability, which tints a mirror with the diffuse colour (a coloured
  diffuse floor with a smooth mirror came out 0.2 to 0.6 % redder in the
  floor's reflections at 8192 spp). That weight is still exact when every
  mixed lobe is a Lambertian of the delta lobe's scaled reflectance (grey
  kd and kt, say), so only such mixtures are mapped. `ks` (Lucent's
  normalised Phong lobe) and the metallic-roughness keys have no Mitsuba
  counterpart. `emission` is a one-sided `area` emitter.
- `[[objects]]`: PLY meshes (`mesh`, with their normals and UVs) and the
  transform translate * rotate (x, then y, then z, fixed axes) * scale;
  objects sharing a mesh file and material become instances of one shape
  group. OBJ files and procedural shapes must be written to PLY first
  (seed.py meshes does), since Mitsuba's OBJ reader and Lucent's differ.
- Light selection: Lucent picks a light in proportion to its power
  (lights.rs); with several lights Mitsuba's `sampling_weight`s are set to
  the same proportions (directional: luminance of the irradiance;
  constant background: pi times its luminance, both over the same pi r^2).
"""
import argparse
import json
import math
import os
import sys
import time
import tomllib

import numpy as np

KNOWN_MATERIAL_KEYS = {"ka", "kd", "ks", "shininess", "kr", "kt", "ior", "roughness", "emission", "texture"}
PBR_KEYS = {"metallic", "metallic_roughness_texture", "transmission", "normal_map", "normal_scale",
            "emission_texture"}


class TwinError(Exception):
    pass


def rgb(x):
    """A Lucent colour (one number or [r, g, b]) as three floats."""
    return [float(x)] * 3 if isinstance(x, (int, float)) else [float(c) for c in x]


def luminance(c):
    return 0.2126 * c[0] + 0.7152 * c[1] + 0.0722 * c[2]


def load_toml(path):
    with open(path, "rb") as f:
        return tomllib.load(f)


def camera_origin(cam):
    """The report's orbit rig: the eye on a sphere of `radius` about `center`."""
    th, ph, rad = math.radians(cam["theta_deg"]), math.radians(cam["phi_deg"]), cam["radius"]
    c = cam["center"]
    return [rad * math.cos(th) * math.cos(ph) + c[0], rad * math.sin(th) + c[1],
            rad * math.cos(th) * math.sin(ph) + c[2]]


def to_world(mi, o):
    t = o.get("translate", [0.0, 0.0, 0.0])
    r = o.get("rotate_deg", [0.0, 0.0, 0.0])
    s = o.get("scale", 1.0)
    s = [s, s, s] if isinstance(s, (int, float)) else s
    # Lucent: translate * rotate (about x, then y, then z, fixed axes) * scale.
    m = mi.ScalarTransform4f().translate(t)
    m = m @ mi.ScalarTransform4f().rotate([0, 0, 1], r[2])
    m = m @ mi.ScalarTransform4f().rotate([0, 1, 0], r[1])
    m = m @ mi.ScalarTransform4f().rotate([1, 0, 0], r[0])
    return m @ mi.ScalarTransform4f().scale(s)


def unit(c):
    return [min(max(x, 0.0), 1.0) for x in c]


def lobes(name, m):
    """Lucent's path-tracer lobes of material `m`: a list of (kind,
    weight [r, g, b], params), weights as Material::bsdf scales them."""
    bad = sorted(set(m) & PBR_KEYS) + sorted(set(m) - KNOWN_MATERIAL_KEYS - PBR_KEYS)
    if bad:
        raise TwinError("material '%s': %s not mapped to Mitsuba" % (name, ", ".join(bad)))
    kd, ks = unit(rgb(m.get("kd", 0.8))), unit(rgb(m.get("ks", 0.0)))
    kr, kt = unit(rgb(m.get("kr", 0.0))), unit(rgb(m.get("kt", 0.0)))
    if max(ks) > 0:
        raise TwinError("material '%s': ks (Lucent's normalised Phong lobe) has no Mitsuba twin" % name)
    most = max(a + b + c for a, b, c in zip(kd, kr, kt))
    s = 1.0 / most if most > 1.0 else 1.0
    out = []
    if max(kd) > 0:
        out.append(("diffuse", [x * s for x in kd], {"texture": m.get("texture")}))
    if max(kr) > 0:
        r = min(max(float(m.get("roughness", 0.0)), 0.0), 1.0)
        out.append(("conductor", [x * s for x in kr], {"alpha": r * r}))
    if max(kt) > 0:
        out.append(("dielectric", [x * s for x in kt], {"ior": float(m.get("ior", 1.0))}))
    return out


def lobe_bsdf(name, kind, weight, params, scene_dir):
    """One lobe as a Mitsuba BSDF of reflectance `weight`."""
    value = {"type": "rgb", "value": weight}
    if kind == "diffuse":
        tex = params["texture"]
        if tex is not None:
            if weight != [1.0, 1.0, 1.0]:
                raise TwinError("material '%s': a texture is mapped only with kd = 1" % name)
            tex = {"file": tex} if isinstance(tex, str) else dict(tex)
            wrap = {"repeat": "repeat", "clamp": "clamp", "mirror": "mirror"}[tex.pop("wrap", "repeat")]
            file = tex.pop("file")
            if tex:
                raise TwinError("material '%s': texture keys %s not mapped" % (name, ", ".join(sorted(tex))))
            # Lucent decodes sRGB to linear when loading, then filters
            # bilinearly with texel centres at half-integers; Mitsuba's
            # bitmap does the same (raw = false); v: see the PLY shape.
            value = {"type": "bitmap", "filename": os.path.normpath(os.path.join(scene_dir, file)),
                     "filter_type": "bilinear", "wrap_mode": wrap, "raw": False}
        return {"type": "twosided", "material": {"type": "diffuse", "reflectance": value}}
    if kind == "conductor":
        if params["alpha"] < 1e-4:
            inner = {"type": "conductor", "material": "none", "specular_reflectance": value}
        else:
            inner = {"type": "roughconductor", "material": "none", "distribution": "ggx",
                     "alpha": params["alpha"], "sample_visible": True, "specular_reflectance": value}
        return {"type": "twosided", "material": inner}
    if params["ior"] == 1.0:
        raise TwinError("material '%s': kt with ior 1 is not mapped" % name)
    return {"type": "dielectric", "int_ior": params["ior"], "ext_ior": 1.0,
            "specular_reflectance": value, "specular_transmittance": value}


def material_bsdf(name, m, scene_dir):
    """Lucent's mixture as nested blendbsdfs (see the module's notes)."""
    ls = lobes(name, m)
    if not ls:
        return {"type": "diffuse", "reflectance": {"type": "rgb", "value": [0.0] * 3}}
    if len(ls) > 1 and any(kind == "diffuse" and p["texture"] for kind, _, p in ls):
        raise TwinError("material '%s': a textured diffuse lobe mixed with others is not mapped "
                        "(Lucent's lobe choice then varies with the texel)" % name)
    means = [sum(w) / 3.0 for _, w, _ in ls]
    total = sum(means)
    probs = [x / total for x in means]
    delta = [k == "dielectric" or (k == "conductor" and p["alpha"] < 1e-4) for k, _, p in ls]
    if any(delta) and not all(delta):
        # See the module's notes: Mitsuba 3.9 mixes the smooth lobes' value
        # into a delta sample's weight, exact only for Lambertian lobes of
        # the same scaled reflectance.
        scaled_w = [[x / p for x in w] for (_, w, _), p in zip(ls, probs)]
        same = all(abs(a - b) < 1e-6 for sw in scaled_w for a, b in zip(sw, scaled_w[0]))
        if not same or any(k == "conductor" and not d for (k, _, _), d in zip(ls, delta)):
            raise TwinError("material '%s': a smooth mirror or dielectric mixed with other lobes is mapped "
                            "only when they are Lambertian of the same colour (Mitsuba 3.9's blendbsdf "
                            "weighs such delta samples with a bias otherwise); give the mirror a roughness "
                            "or make the weights grey" % name)
    scaled = [lobe_bsdf(name, k, [x / p for x in w], prm, scene_dir)
              for (k, w, prm), p in zip(ls, probs)]
    acc, acc_p = scaled[0], probs[0]
    for b, p in zip(scaled[1:], probs[1:]):
        acc_p += p
        acc = {"type": "blendbsdf", "weight": p / acc_p, "bsdf_0": acc, "bsdf_1": b}
    return acc


def check_render(rs):
    if rs.get("integrator", "whitted") != "path":
        raise TwinError("[render] integrator must be \"path\" (Mitsuba has no Whitted model)")
    for key in ("clamp_indirect", "free_delta_bounces"):
        if rs.get(key, 0) != 0:
            raise TwinError("[render] %s must be 0: it biases the path tracer" % key)
    if rs.get("denoise", False):
        raise TwinError("[render] denoise must be false")


def emitters(scene):
    """The lights and the background as Mitsuba emitters, with sampling
    weights in Lucent's proportions when there are several."""
    out = {}
    for i, light in enumerate(scene.get("lights", [])):
        kind = light.get("type")
        if kind == "directional":
            d = [-float(x) for x in light["to_light"]]
            out["light_%d" % i] = ({"type": "directional", "direction": d,
                                    "irradiance": {"type": "rgb", "value": rgb(light.get("intensity", 1.0))}},
                                   luminance(rgb(light.get("intensity", 1.0))))
        elif kind == "point":
            out["light_%d" % i] = ({"type": "point", "position": [float(x) for x in light["position"]],
                                    "intensity": {"type": "rgb", "value": rgb(light.get("intensity", 1.0))}},
                                   None)
        else:
            raise TwinError("light %d: type '%s' not mapped" % (i, kind))
    env = scene.get("environment", {})
    if "map" in env:
        raise TwinError("[environment] map is not mapped here (see envmap.py)")
    bg = rgb(env.get("background", 0.0))
    if max(bg) > 0:
        # Lucent prices a constant sky like a directional light of
        # irradiance pi * luminance (envlight.rs, EnvLight::power).
        out["sky"] = ({"type": "constant", "radiance": {"type": "rgb", "value": bg}}, math.pi * luminance(bg))
    return out


def scene_dict(mi, path):
    scene = load_toml(path)
    scene_dir = os.path.dirname(os.path.abspath(path))
    rs, cam = scene.get("render", {}), scene.get("camera", {})
    check_render(rs)
    missing = [k for k in ("center", "radius", "theta_deg", "phi_deg", "fov_y_deg") if k not in cam]
    if missing:
        raise TwinError("[camera] needs %s (Lucent's defaults depend on the scene's bounds)" % ", ".join(missing))
    c = [float(x) for x in cam["center"]]
    d = {
        "type": "scene",
        "integrator": {"type": "path", "max_depth": int(rs.get("max_depth", 5)),
                       "rr_depth": int(rs.get("rr_depth", 5)), "hide_emitters": False},
        "sensor": {
            "type": "perspective", "fov": float(cam["fov_y_deg"]), "fov_axis": "y", "near_clip": 0.01,
            "to_world": mi.ScalarTransform4f().look_at(origin=camera_origin(cam), target=c, up=[0, 1, 0]),
            "sampler": {"type": "independent"},
            "film": {"type": "hdrfilm", "width": int(rs.get("width", 640)), "height": int(rs.get("height", 360)),
                     "rfilter": {"type": "box"}, "pixel_format": "rgb"},
        },
    }
    lights = emitters(scene)
    materials = scene.get("materials", {})
    area = [o for o in scene.get("objects", []) if "emission" in materials.get(o.get("material"), {})]
    weights = [w for _, w in lights.values()]
    if len(lights) + len(area) > 1 and (area or None in weights):
        raise TwinError("several lights: Lucent's power-based choice is mapped only among directional "
                        "lights and the background")
    for key, (e, w) in lights.items():
        if len(lights) > 1:
            e["sampling_weight"] = w
        d[key] = e
    for name, m in materials.items():
        d["mat_" + name] = material_bsdf(name, m, scene_dir)
    objects = scene.get("objects", [])
    count = {}
    for o in objects:
        count[o.get("mesh")] = count.get(o.get("mesh"), 0) + 1
    groups = {}
    for i, o in enumerate(objects):
        where = "object %d (%s)" % (i, o.get("name", o.get("mesh", o.get("shape"))))
        if "mesh" not in o or not o["mesh"].lower().endswith(".ply"):
            raise TwinError("%s: only PLY meshes are mapped; write a PLY copy" % where)
        if "material" not in o:
            raise TwinError("%s: give a material" % where)
        m = materials[o["material"]]
        mesh_path = os.path.normpath(os.path.join(scene_dir, o["mesh"]))
        # Lucent's texture coordinates have v up (OBJ's convention), and
        # Mitsuba's bitmap puts v = 0 at the top row: its PLY reader flips v
        # only when asked (its OBJ reader does by default).
        shape = {"type": "ply", "filename": mesh_path, "face_normals": False, "flip_tex_coords": True,
                 "bsdf": {"type": "ref", "id": "mat_" + o["material"]}}
        if "emission" in m:
            shape["emitter"] = {"type": "area", "radiance": {"type": "rgb", "value": rgb(m["emission"])}}
        if count[o["mesh"]] == 1:
            shape["to_world"] = to_world(mi, o)
            d["obj_%d" % i] = shape
            continue
        key = (mesh_path, o["material"])
        if key not in groups:
            groups[key] = "grp_%d" % len(groups)
            d[groups[key]] = {"type": "shapegroup", "shape": shape}
        d["inst_%d" % i] = {"type": "instance", "shapegroup": {"type": "ref", "id": groups[key]},
                            "to_world": to_world(mi, o)}
    return d


def render(path, spp, seed, out, variant="llvm_ad_rgb"):
    """Mitsuba's render of the Lucent scene at `path`: `out`.exr and .png,
    one JSON line on stdout."""
    import mitsuba as mi
    mi.set_variant(variant)
    t0 = time.perf_counter()
    s = mi.load_dict(scene_dict(mi, path))
    t_load = time.perf_counter() - t0
    np.array(mi.render(s, spp=1, seed=10**6))  # warm-up (LLVM kernels)
    # Passes of at most 64 spp (one wavefront holds every sample of a
    # pass), each with its own seed, averaged; as cornell.py renders.
    t0 = time.perf_counter()
    acc, done, k = 0.0, 0, 0
    while done < spp:
        n = min(64, spp - done)
        acc = acc + np.array(mi.render(s, spp=n, seed=seed * 1000 + k), dtype=np.float64) * n
        done, k = done + n, k + 1
    img = (acc / spp).astype(np.float32)
    t_render = time.perf_counter() - t0
    bmp = mi.Bitmap(np.ascontiguousarray(img), mi.Bitmap.PixelFormat.RGB)
    bmp.write(out + ".exr")
    bmp.convert(mi.Bitmap.PixelFormat.RGB, mi.Struct.Type.UInt8, srgb_gamma=True).write(out + ".png")
    print(json.dumps({"variant": variant, "spp": spp, "seed": seed, "load_s": round(t_load, 3),
                      "render_s": round(t_render, 3), "s_per_spp": round(t_render / spp, 4),
                      "mean_radiance": [round(float(x), 5) for x in img.reshape(-1, 3).mean(0)]}))


def add_render_args(p):
    p.add_argument("--spp", type=int, default=16)
    p.add_argument("--seed", type=int, default=0)
    p.add_argument("--variant", default="llvm_ad_rgb")
    p.add_argument("--out", required=True)


def main():
    p = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    sub = p.add_subparsers(dest="cmd", required=True)
    r = sub.add_parser("render")
    r.add_argument("scene")
    add_render_args(r)
    d = sub.add_parser("dict")
    d.add_argument("scene")
    a = p.parse_args()
    try:
        if a.cmd == "render":
            render(a.scene, a.spp, a.seed, a.out, a.variant)
        else:
            import mitsuba as mi
            mi.set_variant("scalar_rgb")
            print(scene_dict(mi, a.scene))
    except TwinError as e:
        sys.exit("%s: %s" % (a.scene, e))


if __name__ == "__main__":
    sys.exit(main())
