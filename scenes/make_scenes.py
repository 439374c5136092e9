#!/usr/bin/env python3
"""Writes rtd's bundled glTF scenes (self-contained .gltf files with embedded buffers).

Run from anywhere: `python3 scenes/make_scenes.py`. Uses only the standard library.
Every scene here is authored for rtd and dedicated to the public domain (CC0).
"""
import base64, json, math, os, struct, zlib

HERE = os.path.dirname(os.path.abspath(__file__))


def png_bytes(w, h, pixel):
    """An 8-bit RGB PNG from pixel(x, y) -> (r, g, b) in 0..255."""
    raw = b"".join(b"\x00" + bytes(c for x in range(w) for c in pixel(x, y)) for y in range(h))
    def chunk(t, d):
        return struct.pack(">I", len(d)) + t + d + struct.pack(">I", zlib.crc32(t + d) & 0xFFFFFFFF)
    return b"\x89PNG\r\n\x1a\n" + chunk(b"IHDR", struct.pack(">IIBBBBB", w, h, 8, 2, 0, 0, 0)) + \
        chunk(b"IDAT", zlib.compress(raw, 9)) + chunk(b"IEND", b"")


def sub(a, b): return [a[i] - b[i] for i in range(3)]
def cross(a, b): return [a[1]*b[2]-a[2]*b[1], a[2]*b[0]-a[0]*b[2], a[0]*b[1]-a[1]*b[0]]
def dot(a, b): return sum(a[i]*b[i] for i in range(3))
def norm(a):
    l = math.sqrt(dot(a, a)); return [x / l for x in a]


class Builder:
    def __init__(self):
        self.g = {"asset": {"version": "2.0", "generator": "rtd scenes/make_scenes.py", "copyright": "CC0 1.0"},
                  "scenes": [{"nodes": []}], "scene": 0, "nodes": [], "meshes": [], "materials": [],
                  "accessors": [], "bufferViews": [], "buffers": []}
        self.blob = bytearray()
        self.used = set()

    def _view(self, data, target=None):
        while len(self.blob) % 4: self.blob.append(0)
        off = len(self.blob); self.blob += data
        v = {"buffer": 0, "byteOffset": off, "byteLength": len(data)}
        if target: v["target"] = target
        self.g["bufferViews"].append(v)
        return len(self.g["bufferViews"]) - 1

    def _acc(self, values, comps, kind, target=34962):
        flat = [c for v in values for c in v]
        data = struct.pack("<%df" % len(flat), *flat)
        a = {"bufferView": self._view(data, target), "componentType": 5126, "count": len(values), "type": kind}
        if kind == "VEC3":
            a["min"] = [min(v[i] for v in values) for i in range(3)]
            a["max"] = [max(v[i] for v in values) for i in range(3)]
        self.g["accessors"].append(a)
        return len(self.g["accessors"]) - 1

    def texture(self, png, nearest=False):
        g = self.g
        g.setdefault("images", []).append({"uri": "data:image/png;base64," + base64.b64encode(png).decode()})
        g.setdefault("samplers", []).append({"magFilter": 9728 if nearest else 9729, "minFilter": 9729})
        g.setdefault("textures", []).append({"source": len(g["images"]) - 1, "sampler": len(g["samplers"]) - 1})
        return len(g["textures"]) - 1

    def material(self, name, color=(0.8, 0.8, 0.8), metallic=0.0, roughness=1.0, emissive=None, strength=None,
                 transmission=None, ior=None, specular=None, tex=None, tex_scale=None, double_sided=False):
        pbr = {"baseColorFactor": list(color) + [1.0], "metallicFactor": metallic, "roughnessFactor": roughness}
        m = {"name": name, "pbrMetallicRoughness": pbr, "doubleSided": double_sided}
        ext = {}
        if tex is not None:
            info = {"index": tex}
            if tex_scale:
                info["extensions"] = {"KHR_texture_transform": {"scale": list(tex_scale)}}
                self.used.add("KHR_texture_transform")
            pbr["baseColorTexture"] = info
        if emissive:
            m["emissiveFactor"] = list(emissive)
            if strength:
                ext["KHR_materials_emissive_strength"] = {"emissiveStrength": strength}
        if transmission is not None:
            ext["KHR_materials_transmission"] = {"transmissionFactor": transmission}
        if ior is not None:
            ext["KHR_materials_ior"] = {"ior": ior}
        if specular is not None:
            ext["KHR_materials_specular"] = {"specularFactor": specular}
        if ext:
            m["extensions"] = ext; self.used.update(ext)
        self.g["materials"].append(m)
        return len(self.g["materials"]) - 1

    def mesh(self, name, tris, material, smooth_normals=None, uvs=None):
        """tris: list of (p0, p1, p2) counter-clockwise from the front. Non-indexed."""
        pos = [p for t in tris for p in t]
        if smooth_normals is None:
            nrm = []
            for t in tris:
                n = norm(cross(sub(t[1], t[0]), sub(t[2], t[0]))); nrm += [n, n, n]
        else:
            nrm = smooth_normals
        prim = {"attributes": {"POSITION": self._acc(pos, 3, "VEC3"), "NORMAL": self._acc(nrm, 3, "VEC3")},
                "material": material}
        if uvs is not None:
            prim["attributes"]["TEXCOORD_0"] = self._acc(uvs, 2, "VEC2")
        self.g["meshes"].append({"name": name, "primitives": [prim]})
        self.node({"name": name, "mesh": len(self.g["meshes"]) - 1})

    def node(self, n):
        self.g["nodes"].append(n); self.g["scenes"][0]["nodes"].append(len(self.g["nodes"]) - 1)

    def camera(self, name, eye, target, yfov_deg):
        f = norm(sub(target, eye))
        # glTF cameras look down -Z: build the rotation whose -Z is f, +Y close to world up.
        r = norm(cross(f, [0, 1, 0])); u = cross(r, f); b = [-x for x in f]
        m = [r, u, b]  # columns
        # rotation matrix (columns r,u,b) to quaternion
        m00, m01, m02 = r[0], u[0], b[0]; m10, m11, m12 = r[1], u[1], b[1]; m20, m21, m22 = r[2], u[2], b[2]
        tr = m00 + m11 + m22
        if tr > 0:
            s = math.sqrt(tr + 1.0) * 2; q = [(m21 - m12) / s, (m02 - m20) / s, (m10 - m01) / s, 0.25 * s]
        elif m00 > m11 and m00 > m22:
            s = math.sqrt(1.0 + m00 - m11 - m22) * 2; q = [0.25 * s, (m01 + m10) / s, (m02 + m20) / s, (m21 - m12) / s]
        elif m11 > m22:
            s = math.sqrt(1.0 + m11 - m00 - m22) * 2; q = [(m01 + m10) / s, 0.25 * s, (m12 + m21) / s, (m02 - m20) / s]
        else:
            s = math.sqrt(1.0 + m22 - m00 - m11) * 2; q = [(m02 + m20) / s, (m12 + m21) / s, 0.25 * s, (m10 - m01) / s]
        self.g.setdefault("cameras", []).append({"name": name, "type": "perspective",
                                                 "perspective": {"yfov": math.radians(yfov_deg), "znear": 0.01}})
        self.node({"name": name, "camera": len(self.g["cameras"]) - 1, "translation": eye, "rotation": q})

    def point_light(self, name, pos, color, intensity):
        self.used.add("KHR_lights_punctual")
        ext = self.g.setdefault("extensions", {}).setdefault("KHR_lights_punctual", {"lights": []})
        ext["lights"].append({"name": name, "type": "point", "color": list(color), "intensity": intensity})
        self.node({"name": name, "translation": pos, "extensions": {"KHR_lights_punctual": {"light": len(ext["lights"]) - 1}}})

    def write(self, filename):
        self.g["buffers"] = [{"byteLength": len(self.blob),
                              "uri": "data:application/octet-stream;base64," + base64.b64encode(bytes(self.blob)).decode()}]
        if self.used:
            self.g["extensionsUsed"] = sorted(self.used)
        for k in [k for k, v in self.g.items() if v == [] ]:
            del self.g[k]
        with open(os.path.join(HERE, filename), "w") as f:
            json.dump(self.g, f, indent=1)
        print("wrote", filename)


def quad(a, b, c, d):
    return [(a, b, c), (a, c, d)]


def oriented_quad(pts, inside):
    """A quad whose front faces the point `inside` (or away from it if inside is negative-flagged)."""
    a, b, c, d = pts
    n = cross(sub(b, a), sub(c, a))
    center = [sum(p[i] for p in pts) / 4 for i in range(3)]
    if dot(n, sub(inside, center)) < 0:
        a, b, c, d = d, c, b, a
    return quad(a, b, c, d)


def box_tris(center, size, outward=True):
    cx, cy, cz = center; sx, sy, sz = [s / 2 for s in size]
    P = lambda i, j, k: [cx + i * sx, cy + j * sy, cz + k * sz]
    faces = [[P(1,-1,-1), P(1,1,-1), P(1,1,1), P(1,-1,1)], [P(-1,-1,-1), P(-1,-1,1), P(-1,1,1), P(-1,1,-1)],
             [P(-1,1,-1), P(-1,1,1), P(1,1,1), P(1,1,-1)], [P(-1,-1,-1), P(1,-1,-1), P(1,-1,1), P(-1,-1,1)],
             [P(-1,-1,1), P(1,-1,1), P(1,1,1), P(-1,1,1)], [P(-1,-1,-1), P(-1,1,-1), P(1,1,-1), P(1,-1,-1)]]
    tris = []
    for f in faces:
        c = [sum(p[i] for p in f) / 4 for i in range(3)]
        away = [2 * c[i] - center[i] for i in range(3)]
        tris += oriented_quad(f, away if outward else center)
    return tris


def sphere(center, r, nu=48, nv=24):
    tris, nrm, uvs = [], [], []
    def pt(i, j):
        th = math.pi * j / nv; ph = 2 * math.pi * i / nu
        n = [math.sin(th) * math.cos(ph), math.cos(th), -math.sin(th) * math.sin(ph)]
        return [center[k] + r * n[k] for k in range(3)], n, [i / nu, j / nv]
    for j in range(nv):
        for i in range(nu):
            a, b, c, d = pt(i, j), pt(i, j + 1), pt(i + 1, j + 1), pt(i + 1, j)
            for t in ([a, b, c], [a, c, d]):
                if dot(cross(sub(t[1][0], t[0][0]), sub(t[2][0], t[0][0])), cross(sub(t[1][0], t[0][0]), sub(t[2][0], t[0][0]))) < 1e-20:
                    continue
                tris.append(tuple(v[0] for v in t)); nrm += [v[1] for v in t]; uvs += [v[2] for v in t]
    return tris, nrm, uvs


def cornell_box():
    """The Cornell box from the measured data at graphics.cornell.edu (mm, scaled to metres)."""
    b = Builder()
    s = 0.001
    P = lambda x, y, z: [x * s, y * s, z * s]
    inside = P(278, 274, 280)
    white = b.material("white", (0.725, 0.71, 0.68))
    red = b.material("red", (0.63, 0.065, 0.05))
    green = b.material("green", (0.14, 0.45, 0.091))
    light = b.material("light", (0.78, 0.78, 0.78), emissive=(1.0, 0.7059, 0.2353), strength=17.0)
    walls = []
    walls += oriented_quad([P(552.8, 0, 0), P(0, 0, 0), P(0, 0, 559.2), P(549.6, 0, 559.2)], inside)  # floor
    walls += oriented_quad([P(556, 548.8, 0), P(556, 548.8, 559.2), P(0, 548.8, 559.2), P(0, 548.8, 0)], inside)  # ceiling
    walls += oriented_quad([P(549.6, 0, 559.2), P(0, 0, 559.2), P(0, 548.8, 559.2), P(556, 548.8, 559.2)], inside)  # back
    b.mesh("walls", walls, white)
    b.mesh("green-wall", oriented_quad([P(0, 0, 559.2), P(0, 0, 0), P(0, 548.8, 0), P(0, 548.8, 559.2)], inside), green)
    b.mesh("red-wall", oriented_quad([P(552.8, 0, 0), P(549.6, 0, 559.2), P(556, 548.8, 559.2), P(556, 548.8, 0)], inside), red)
    # The light sits 0.5 mm below the ceiling, facing down.
    b.mesh("light", oriented_quad([P(343, 548.3, 227), P(343, 548.3, 332), P(213, 548.3, 332), P(213, 548.3, 227)], P(278, 0, 280)), light)
    def block(top, h, name):
        c = [sum(p[i] for p in top) / 4 for i in range(3)]
        center = [c[0], h / 2, c[2]]
        tris = oriented_quad([P(*p) for p in top], [c[0] * s, 2 * h * s, c[2] * s])
        for i in range(4):
            p, q = top[i], top[(i + 1) % 4]
            face = [P(p[0], 0, p[2]), P(p[0], h, p[2]), P(q[0], h, q[2]), P(q[0], 0, q[2])]
            fc = [(p[0] + q[0]) / 2, h / 2, (p[2] + q[2]) / 2]
            tris += oriented_quad(face, [(2 * fc[k] - center[k]) * s for k in range(3)])
        b.mesh(name, tris, white)
    block([(130, 165, 65), (82, 165, 225), (240, 165, 272), (290, 165, 114)], 165.0, "short-block")
    block([(423, 330, 247), (265, 330, 296), (314, 330, 456), (472, 330, 406)], 330.0, "tall-block")
    # Camera from the measured data: 35 mm lens on 25 mm film, at (278, 273, -800) looking +z.
    b.camera("camera", P(278, 273, -800), P(278, 273, 0), math.degrees(2 * math.atan(12.5 / 35)))
    b.write("cornell-box.gltf")


def glass_and_metals():
    b = Builder()
    floor_tex = b.texture(png_bytes(64, 64, lambda x, y: (200, 200, 200) if (x // 8 + y // 8) % 2 else (60, 60, 70)))
    floor = b.material("checker-floor", tex=floor_tex, tex_scale=(6, 6), roughness=0.6)
    b.mesh("floor", oriented_quad([[-4, 0, -4], [4, 0, -4], [4, 0, 4], [-4, 0, 4]], [0, 1, 0]), floor,
           uvs=[[0, 0], [1, 0], [1, 1], [0, 0], [1, 1], [0, 1]])
    b.mesh("backdrop", oriented_quad([[-4, 0, -2.5], [4, 0, -2.5], [4, 4, -2.5], [-4, 4, -2.5]], [0, 1, 0]),
           b.material("backdrop", (0.55, 0.6, 0.7)))
    mats = [
        b.material("clear-glass", (1, 1, 1), roughness=0.0, transmission=1.0, ior=1.5),
        b.material("frosted-glass", (0.85, 0.95, 1.0), roughness=0.35, transmission=1.0, ior=1.45),
        b.material("gold", (1.0, 0.766, 0.336), metallic=1.0, roughness=0.25),
        b.material("chrome", (0.95, 0.93, 0.88), metallic=1.0, roughness=0.0),
        b.material("red-plastic", (0.8, 0.05, 0.04), roughness=0.15, specular=1.0),
    ]
    for i, m in enumerate(mats):
        t, n, uv = sphere([-2.0 + i * 1.0, 0.45, 0.0], 0.45)
        b.mesh("sphere-%d" % i, t, m, smooth_normals=n, uvs=uv)
    lamp = b.material("lamp", (1, 1, 1), emissive=(1, 1, 1), strength=12.0)
    b.mesh("softbox", oriented_quad([[-1.5, 3.2, -0.5], [1.5, 3.2, -0.5], [1.5, 3.2, 1.0], [-1.5, 3.2, 1.0]], [0, 0, 0]), lamp)
    b.mesh("rim-light", oriented_quad([[2.5, 0.2, -1.8], [3.5, 0.2, -1.0], [3.5, 1.8, -1.0], [2.5, 1.8, -1.8]], [0, 0.5, 0]),
           b.material("rim", (1, 1, 1), emissive=(0.6, 0.8, 1.0), strength=6.0))
    b.camera("camera", [0.0, 1.5, 5.6], [0.0, 0.5, 0.0], 36)
    b.write("glass-and-metals.gltf")


def textured_interior():
    """A room lit only indirectly: the lamp hides in a cove and faces the ceiling."""
    b = Builder()
    checker = b.texture(png_bytes(64, 64, lambda x, y: (180, 160, 130) if (x // 4 + y // 4) % 2 else (90, 70, 50)))
    stripes = b.texture(png_bytes(64, 64, lambda x, y: (200, 200, 190) if (x // 3) % 2 else (120, 140, 170)))
    floor = b.material("parquet", tex=checker, tex_scale=(4, 4), roughness=0.5)
    wall = b.material("wallpaper", tex=stripes, tex_scale=(3, 3))
    plain = b.material("plaster", (0.8, 0.78, 0.75))
    W, D, H = 4.0, 5.0, 2.8
    inside = [0, 1.4, 0]
    uv4 = [[0, 0], [1, 0], [1, 1], [0, 0], [1, 1], [0, 1]]
    b.mesh("floor", oriented_quad([[-W/2, 0, -D/2], [W/2, 0, -D/2], [W/2, 0, D/2], [-W/2, 0, D/2]], inside), floor, uvs=uv4)
    b.mesh("ceiling", oriented_quad([[-W/2, H, -D/2], [W/2, H, -D/2], [W/2, H, D/2], [-W/2, H, D/2]], inside), plain)
    for name, q in [("back", [[-W/2, 0, -D/2], [W/2, 0, -D/2], [W/2, H, -D/2], [-W/2, H, -D/2]]),
                    ("left", [[-W/2, 0, -D/2], [-W/2, 0, D/2], [-W/2, H, D/2], [-W/2, H, -D/2]]),
                    ("right", [[W/2, 0, -D/2], [W/2, 0, D/2], [W/2, H, D/2], [W/2, H, -D/2]]),
                    ("front", [[-W/2, 0, D/2], [W/2, 0, D/2], [W/2, H, D/2], [-W/2, H, D/2]])]:
        b.mesh(name, oriented_quad(q, inside), wall, uvs=uv4)
    # Cove: a shelf along the back wall hides an upward-facing lamp.
    b.mesh("cove", box_tris([0, 2.3, -D/2 + 0.3], [W - 0.2, 0.04, 0.6]) +
           box_tris([0, 2.45, -D/2 + 0.58], [W - 0.2, 0.3, 0.04]), plain)
    lamp = b.material("cove-lamp", (1, 1, 1), emissive=(1.0, 0.85, 0.6), strength=250.0)
    b.mesh("cove-lamp", oriented_quad([[-1.6, 2.33, -D/2 + 0.1], [1.6, 2.33, -D/2 + 0.1], [1.6, 2.33, -D/2 + 0.5], [-1.6, 2.33, -D/2 + 0.5]], [0, H, -D/2 + 0.3]), lamp)
    wood = b.material("table", (0.45, 0.28, 0.15), roughness=0.4)
    b.mesh("table", box_tris([0.3, 0.72, -0.3], [1.4, 0.05, 0.8]) + box_tris([-0.3, 0.36, -0.6], [0.06, 0.72, 0.06]) +
           box_tris([0.9, 0.36, -0.6], [0.06, 0.72, 0.06]) + box_tris([-0.3, 0.36, 0.0], [0.06, 0.72, 0.06]) +
           box_tris([0.9, 0.36, 0.0], [0.06, 0.72, 0.06]), wood)
    t, n, uv = sphere([0.5, 0.92, -0.3], 0.17)
    b.mesh("vase", t, b.material("ceramic", (0.2, 0.35, 0.6), roughness=0.2), smooth_normals=n, uvs=uv)
    b.mesh("cabinet", box_tris([-1.5, 0.5, -1.8], [0.8, 1.0, 0.6]), b.material("cabinet", (0.7, 0.7, 0.65), roughness=0.7))
    b.camera("camera", [1.6, 1.6, 2.3], [-0.2, 0.9, -1.0], 55)
    b.write("textured-interior.gltf")


def small_lights():
    """A dark scene lit by a few tiny, intense emitters and a point light: fireflies and caustics."""
    b = Builder()
    b.mesh("floor", oriented_quad([[-3, 0, -3], [3, 0, -3], [3, 0, 3], [-3, 0, 3]], [0, 1, 0]), b.material("floor", (0.5, 0.5, 0.5), roughness=0.8))
    b.mesh("wall", oriented_quad([[-3, 0, -1.5], [3, 0, -1.5], [3, 3, -1.5], [-3, 3, -1.5]], [0, 1, 0]), b.material("wall", (0.6, 0.55, 0.5)))
    for i, (c, col) in enumerate([([-1.2, 1.6, -0.6], (1.0, 0.3, 0.1)), ([0.1, 2.0, 0.4], (0.3, 0.6, 1.0)), ([1.3, 0.9, -0.2], (1.0, 0.9, 0.7))]):
        b.mesh("bulb-%d" % i, box_tris(c, [0.04, 0.04, 0.04]), b.material("bulb-%d" % i, (1, 1, 1), emissive=col, strength=3000.0))
    t, n, uv = sphere([-0.4, 0.4, 0.2], 0.4)
    b.mesh("glass-ball", t, b.material("glass", (1, 1, 1), roughness=0.0, transmission=1.0, ior=1.5), smooth_normals=n, uvs=uv)
    t, n, uv = sphere([0.8, 0.3, 0.5], 0.3)
    b.mesh("copper-ball", t, b.material("copper", (0.955, 0.638, 0.538), metallic=1.0, roughness=0.15), smooth_normals=n, uvs=uv)
    b.mesh("pedestal", box_tris([1.3, 0.35, -0.2], [0.4, 0.7, 0.4]), b.material("pedestal", (0.7, 0.7, 0.7), roughness=0.5))
    # glTF point intensities are candela (photometric); rtd divides by 683 lm/W, so this is 4 W/sr.
    b.point_light("point", [-2.0, 2.5, 1.5], (1.0, 0.95, 0.9), 4.0 * 683)
    b.camera("camera", [0.0, 1.4, 3.6], [0.0, 0.7, 0.0], 45)
    b.write("small-lights.gltf")


if __name__ == "__main__":
    cornell_box(); glass_and_metals(); textured_interior(); small_lights()
