"""The Cycles single-image benchmark (issue 35): procedural scenes built and rendered by
Blender itself (nothing downloaded), so that the scenes are not made by the hands that tune
the method, nor traced by our own ray tracer.

Usage: blender -b --factory-startup --python-exit-code 1 --python cycles_scenes.py --
       OUT_DIR PARAMS_JSON
PARAMS_JSON: {"size": 256, "truth_spp": 512, "pinhole_spp": 128, "layer_spp": 16,
              "scenes": [names] or null for all}
Per scene, OUT_DIR/<name>/:
  truth.exr    thin-lens depth of field (Cycles, disk aperture), RGBA, truth_spp samples
  pinhole.exr  multilayer, pinhole camera: All.Combined + All.Depth (Cycles' Z pass: planar
               depth of the first sample of each pixel, so a mixed edge pixel carries one
               side's depth), and Sky (the world alone)
  layers.exr   multilayer, pinhole, transparent film: one view layer per object group
               (Combined + Depth), each group rendered alone
  camera.json  lens, sensor, f-stop, focus distance, size, groups front to back, seconds
Prints LENSBLUR_CYCLES <name> <json> per scene.

Camera at (0, 0, 1.6) looking along +Y, so a point's planar depth is its y. No denoising
(Debian's Blender has no OpenImageDenoise), fixed seed, no adaptive sampling. Diffuse
surfaces see a dim copy of the sky and no other surface (no diffuse bounce): the truth's
noise stays low, and the camera and glossy rays see the bright HDR sky."""
import json
import math
import os
import random
import sys
import time

import bpy

EYE = 1.6
SENSOR = 36.0


def half_width(depth, lens):
    """Half the frame's width at planar `depth` for a `lens` mm lens on a 36 mm sensor."""
    return depth * SENSOR / (2.0 * lens)


# --- materials --------------------------------------------------------------------------

def material(name, colour, roughness=None, emit=0.0, checker=None):
    """Diffuse `colour` (optionally checkered with `checker` at 8 squares a metre), a sharp
    glossy coat when `roughness` is given, or an emitter of strength `emit`."""
    mat = bpy.data.materials.new(name)
    mat.use_nodes = True
    nodes, links = mat.node_tree.nodes, mat.node_tree.links
    nodes.clear()
    out = nodes.new("ShaderNodeOutputMaterial")
    if emit > 0.0:
        shader = nodes.new("ShaderNodeEmission")
        shader.inputs["Color"].default_value = (*colour, 1.0)
        shader.inputs["Strength"].default_value = emit
        links.new(shader.outputs[0], out.inputs["Surface"])
        return mat
    diffuse = nodes.new("ShaderNodeBsdfDiffuse")
    diffuse.inputs["Color"].default_value = (*colour, 1.0)
    if checker is not None:
        coords = nodes.new("ShaderNodeTexCoord")
        tex = nodes.new("ShaderNodeTexChecker")
        tex.inputs["Scale"].default_value = 8.0
        tex.inputs["Color1"].default_value = (*colour, 1.0)
        tex.inputs["Color2"].default_value = (*checker, 1.0)
        links.new(coords.outputs["Object"], tex.inputs["Vector"])
        links.new(tex.outputs["Color"], diffuse.inputs["Color"])
    shader = diffuse
    if roughness is not None:
        glossy = nodes.new("ShaderNodeBsdfGlossy")
        glossy.inputs["Roughness"].default_value = roughness
        mix = nodes.new("ShaderNodeMixShader")
        mix.inputs["Fac"].default_value = 0.5
        links.new(diffuse.outputs[0], mix.inputs[1])
        links.new(glossy.outputs[0], mix.inputs[2])
        shader = mix
    links.new(shader.outputs[0], out.inputs["Surface"])
    return mat


def new_world():
    """A new world node tree for the scene: (nodes, links)."""
    w = bpy.data.worlds.new("Sky")
    bpy.context.scene.world = w
    # The dim sky is sampled as a light (multiple importance): hit only by chance, its light
    # would be the noisiest part of every diffuse surface.
    w.cycles.sampling_method = "AUTOMATIC"
    w.use_nodes = True
    nodes, links = w.node_tree.nodes, w.node_tree.links
    nodes.clear()
    return nodes, links


def seen_sky(nodes, links, colour, strength):
    """The world's output: the `colour` socket times `strength` for camera and glossy rays, a
    twentieth of it for diffuse rays (less noise in the truth, the same sky in view)."""
    bright = nodes.new("ShaderNodeBackground")
    bright.inputs["Strength"].default_value = strength
    dim = nodes.new("ShaderNodeBackground")
    dim.inputs["Strength"].default_value = 0.05 * strength
    links.new(colour, bright.inputs["Color"])
    links.new(colour, dim.inputs["Color"])
    path = nodes.new("ShaderNodeLightPath")
    seen = nodes.new("ShaderNodeMath")
    seen.operation = "MAXIMUM"
    links.new(path.outputs["Is Camera Ray"], seen.inputs[0])
    links.new(path.outputs["Is Glossy Ray"], seen.inputs[1])
    mix = nodes.new("ShaderNodeMixShader")
    links.new(seen.outputs[0], mix.inputs["Fac"])
    links.new(dim.outputs[0], mix.inputs[1])
    links.new(bright.outputs[0], mix.inputs[2])
    out = nodes.new("ShaderNodeOutputWorld")
    links.new(mix.outputs[0], out.inputs["Surface"])


def world(horizon, zenith, strength):
    """An HDR sky: `horizon` to `zenith` colour times `strength` (see `seen_sky`)."""
    nodes, links = new_world()
    coords = nodes.new("ShaderNodeTexCoord")
    xyz = nodes.new("ShaderNodeSeparateXYZ")
    ramp = nodes.new("ShaderNodeValToRGB")
    ramp.color_ramp.elements[0].color = (*horizon, 1.0)
    ramp.color_ramp.elements[1].color = (*zenith, 1.0)
    ramp.color_ramp.elements[1].position = 0.6
    links.new(coords.outputs["Generated"], xyz.inputs[0])
    links.new(xyz.outputs["Z"], ramp.inputs["Fac"])
    seen_sky(nodes, links, ramp.outputs["Color"], strength)


def sun(strength, elevation_deg=40.0, azimuth_deg=30.0):
    light = bpy.data.lights.new("Sun", "SUN")
    light.energy = strength
    light.angle = 0.0
    obj = bpy.data.objects.new("Sun", light)
    obj.rotation_euler = (math.radians(90.0 - elevation_deg), 0.0, math.radians(azimuth_deg))
    bpy.context.scene.collection.objects.link(obj)


# --- geometry ---------------------------------------------------------------------------

class Group:
    """One object group: a collection, rendered alone as one view layer. Geometry is
    accumulated into one mesh per material."""

    def __init__(self, name):
        self.name = name
        self.collection = bpy.data.collections.new(name)
        bpy.context.scene.collection.children.link(self.collection)
        self.meshes = {}

    def _mesh(self, mat):
        return self.meshes.setdefault(mat.name, (mat, [], []))

    def add(self, mat, verts, faces):
        _, vs, fs = self._mesh(mat)
        base = len(vs)
        vs.extend(verts)
        fs.extend(tuple(base + i for i in f) for f in faces)

    def box(self, mat, lo, hi):
        (x0, y0, z0), (x1, y1, z1) = lo, hi
        v = [(x0, y0, z0), (x1, y0, z0), (x1, y1, z0), (x0, y1, z0),
             (x0, y0, z1), (x1, y0, z1), (x1, y1, z1), (x0, y1, z1)]
        f = [(0, 3, 2, 1), (4, 5, 6, 7), (0, 1, 5, 4), (1, 2, 6, 5), (2, 3, 7, 6), (3, 0, 4, 7)]
        self.add(mat, v, f)

    def quad(self, mat, corners):
        self.add(mat, corners, [(0, 1, 2, 3)])

    def tube(self, mat, points, radius, sides=6):
        """A polyline swept by a `sides`-gon of `radius` (wires, strands)."""
        rings = []
        for i, p in enumerate(points):
            a, b = points[max(i - 1, 0)], points[min(i + 1, len(points) - 1)]
            t = [b[k] - a[k] for k in range(3)]
            n = math.sqrt(sum(c * c for c in t)) or 1.0
            t = [c / n for c in t]
            helper = (0.0, 1.0, 0.0) if abs(t[1]) < 0.9 else (1.0, 0.0, 0.0)
            u = cross(t, helper)
            un = math.sqrt(sum(c * c for c in u))
            u = [c / un for c in u]
            w = cross(t, u)
            rings.append([tuple(p[k] + radius * (math.cos(2 * math.pi * s / sides) * u[k]
                                                  + math.sin(2 * math.pi * s / sides) * w[k]) for k in range(3))
                          for s in range(sides)])
        verts = [v for ring in rings for v in ring]
        faces = [(r * sides + s, r * sides + (s + 1) % sides, (r + 1) * sides + (s + 1) % sides, (r + 1) * sides + s)
                 for r in range(len(points) - 1) for s in range(sides)]
        self.add(mat, verts, faces)

    def sphere(self, mat, centre, radius, rings=12, segments=24):
        verts, faces = [], []
        for i in range(rings + 1):
            theta = math.pi * i / rings
            for j in range(segments):
                phi = 2 * math.pi * j / segments
                verts.append((centre[0] + radius * math.sin(theta) * math.cos(phi),
                              centre[1] + radius * math.sin(theta) * math.sin(phi),
                              centre[2] + radius * math.cos(theta)))
        for i in range(rings):
            for j in range(segments):
                a, b = i * segments + j, i * segments + (j + 1) % segments
                faces.append((a, b, b + segments, a + segments))
        self.add(mat, verts, faces)

    def build(self):
        for mat, verts, faces in self.meshes.values():
            mesh = bpy.data.meshes.new(f"{self.name}-{mat.name}")
            mesh.from_pydata(verts, [], faces)
            mesh.materials.append(mat)
            self.collection.objects.link(bpy.data.objects.new(mesh.name, mesh))


def cross(a, b):
    return (a[1] * b[2] - a[2] * b[1], a[2] * b[0] - a[0] * b[2], a[0] * b[1] - a[1] * b[0])


def diagonal_fence(group, mat, depth, half, z0, z1, spacing, radius, angle=45.0):
    """Chain-link: two families of straight wires at +-`angle` degrees in the plane y = depth,
    clipped to x in [-half, half], z in [z0, z1]."""
    slope = math.tan(math.radians(angle))
    span = (z1 - z0) / slope
    for sign in (1.0, -1.0):
        start = -half - span
        while start < half + span:
            # The wire z = z0 + sign * slope * (x - start) (mirrored for -1), clipped.
            x_a, x_b = start, start + span
            pts = [(x_a, z0), (x_b, z1)] if sign > 0 else [(x_b, z0), (x_a, z1)]
            (xa, za), (xb, zb) = pts
            clipped = clip_segment(xa, za, xb, zb, -half, half)
            if clipped and clipped[1][0] - clipped[0][0] > 1e-4:
                (xa, za), (xb, zb) = clipped
                group.tube(mat, [(xa, depth, za), (xb, depth, zb)], radius)
            start += spacing


def clip_segment(xa, za, xb, zb, x_lo, x_hi):
    if xa > xb:
        xa, za, xb, zb = xb, zb, xa, za
    if xb < x_lo or xa > x_hi:
        return None
    def at(x):
        return za + (zb - za) * (x - xa) / (xb - xa)
    a = (max(xa, x_lo), at(max(xa, x_lo)))
    b = (min(xb, x_hi), at(min(xb, x_hi)))
    return a, b


def grid(group, mat, depth, half, z0, z1, spacing, radius):
    x = -half
    while x <= half:
        group.tube(mat, [(x, depth, z0), (x, depth, z1)], radius)
        x += spacing
    z = z0
    while z <= z1:
        group.tube(mat, [(-half, depth, z), (half, depth, z)], radius)
        z += spacing


def courtyard(group, depth, lens, rng, sunlit=True):
    """A back wall at `depth` with windows, a ground plane up to it, side walls: the frame
    below eye level plus a metre, sky above."""
    h = half_width(depth, lens) * 1.6
    wall = material("wall", (0.75, 0.6, 0.45), checker=(0.55, 0.4, 0.3))
    window = material("window", (0.05, 0.07, 0.1), roughness=0.05)
    ground = material("ground", (0.5, 0.5, 0.45), checker=(0.35, 0.35, 0.3))
    group.box(wall, (-h, depth, -1.0), (h, depth + 0.5, EYE + 0.3 * half_width(depth, lens)))
    group.quad(ground, [(-h, 0.2, 0.0), (h, 0.2, 0.0), (h, depth, 0.0), (-h, depth, 0.0)])
    step = max(0.4, h / 4.0)
    x = -h + step / 2
    while x < h:
        z = 0.4 + rng.random() * (EYE - 0.2)
        group.box(window, (x, depth - 0.05, z), (x + step * 0.45, depth, z + step * 0.5))
        x += step


# --- scenes -----------------------------------------------------------------------------
# Each returns (lens mm, f-stop, focus distance m, [groups front to back]).

def fence_over_yard(rng, lens, sky, sun_strength, depth, wire, spacing, radius, angle, yard_depth):
    """A chain-link fence at `depth` filling the frame in front of a courtyard at
    `yard_depth` under an HDR sky `sky` (horizon, zenith, strength)."""
    world(*sky)
    sun(sun_strength)
    fence, yard = Group("fence"), Group("yard")
    h = half_width(depth, lens) * 1.3
    diagonal_fence(fence, wire, depth, h, EYE - h, EYE + h, spacing, radius, angle)
    courtyard(yard, yard_depth, lens, rng)
    return fence, yard


def fence_near_hdr(rng):
    """The issue's case: 85 mm f/2 focused 12 m on a sunlit courtyard under a bright sky,
    a chain-link fence of ~1.5 px diagonal wires 1 m away (CoC ~12 px at 256^2), a small
    bright bead on the fence that must open into a large disc."""
    wire = material("wire", (0.35, 0.35, 0.33), roughness=0.3)
    sky = ((5.0, 5.5, 6.0), (1.5, 2.5, 6.0), 1.5)
    fence, yard = fence_over_yard(rng, 85.0, sky, 2.5, 1.0, wire, 0.05, 0.0012, 45.0, 12.0)
    fence.sphere(material("bead", (1.0, 0.9, 0.7), emit=60.0), (0.05, 0.99, EYE + 0.04), 0.003)
    return 85.0, 2.0, 12.0, [fence, yard]


def fence_far_focus_near(rng):
    """Focus in front (a checkered ball 1.2 m away), a fence 3 m away blurred ~9 px, a lit
    wall at 15 m and sky: 85 mm f/1.4."""
    lens = 85.0
    world((4.0, 4.5, 5.0), (1.0, 2.0, 5.0), 1.0)
    sun(2.1)
    subject, fence, yard = Group("subject"), Group("fence"), Group("yard")
    subject.sphere(material("ball", (0.8, 0.2, 0.1), checker=(0.9, 0.85, 0.2)), (-0.05, 1.2, EYE - 0.06), 0.09)
    subject.tube(material("post", (0.2, 0.25, 0.3)), [(0.12, 1.25, EYE - 0.6), (0.12, 1.25, EYE + 0.1)], 0.012)
    wire = material("wire", (0.6, 0.6, 0.58), roughness=0.3)
    h = half_width(3.0, lens) * 1.3
    diagonal_fence(fence, wire, 3.0, h, EYE - h, EYE + h, 0.09, 0.004)
    courtyard(yard, 15.0, lens, rng)
    return lens, 1.4, 1.2, [subject, fence, yard]


def fence_near_135(rng):
    """A fence 2 m away at 135 mm f/4 focused 20 m on a courtyard (CoC ~7 px at 256^2),
    wires at 30 degrees."""
    wire = material("wire", (0.25, 0.25, 0.25), roughness=0.4)
    sky = ((6.0, 6.0, 6.5), (2.0, 3.0, 6.5), 1.5)
    return 135.0, 4.0, 20.0, list(fence_over_yard(rng, 135.0, sky, 3.3, 2.0, wire, 0.04, 0.0009, 30.0, 20.0))


def grid_near(rng):
    """A square wire grid 0.4 m in front of a 35 mm f/1.4 lens focused on boxes at 5 m, a
    bright sky behind (grid CoC ~7 px)."""
    lens = 35.0
    world((6.0, 6.0, 6.0), (1.5, 2.0, 5.0), 1.0)
    sun(2.5)
    near, boxes, yard = Group("grid"), Group("boxes"), Group("yard")
    h = half_width(0.4, lens) * 1.2
    grid(near, material("grid", (0.5, 0.45, 0.4), roughness=0.3), 0.4, h, EYE - h, EYE + h, 0.03, 0.001)
    for i in range(5):
        x = -1.8 + 0.9 * i
        colour = (rng.random() * 0.8 + 0.1, rng.random() * 0.8 + 0.1, rng.random() * 0.8 + 0.1)
        boxes.box(material(f"box{i}", colour, checker=(0.9, 0.9, 0.9)), (x - 0.3, 5.0, 0.0), (x + 0.3, 5.6, 0.6 + rng.random() * 1.2))
    courtyard(yard, 25.0, lens, rng)
    return lens, 1.4, 5.0, [near, boxes, yard]


def foliage_holes(rng):
    """A screen of leaves with holes 2.5 m away (CoC ~6 px) against a bright sky and a tree
    line in focus at 8 m: 135 mm f/2.8."""
    lens = 135.0
    world((7.0, 7.0, 7.5), (2.0, 3.0, 7.0), 1.5)
    sun(2.9)
    leaves, trees = Group("leaves"), Group("trees")
    h = half_width(2.5, lens) * 1.2
    greens = [material(f"leaf{i}", (0.1 + 0.1 * i, 0.35 + 0.1 * i, 0.05)) for i in range(3)]
    for _ in range(1400):
        cx, cz = rng.uniform(-h, h), EYE + rng.uniform(-h, h)
        if (cx + 0.05) ** 2 + (cz - EYE) ** 2 < 0.05 ** 2 or (cx - 0.15) ** 2 + (cz - EYE - 0.1) ** 2 < 0.03 ** 2:
            continue  # a hole the sky shows through
        size, turn = rng.uniform(0.012, 0.03), rng.uniform(0.0, math.pi)
        pts = [(cx + size * math.cos(turn + a) * (1.0 if k % 2 == 0 else 0.5), 2.5 + rng.uniform(-0.05, 0.05),
                cz + size * math.sin(turn + a) * (1.0 if k % 2 == 0 else 0.5))
               for k, a in enumerate([0.0, math.pi / 2, math.pi, 3 * math.pi / 2])]
        leaves.quad(rng.choice(greens), pts)
    bark = material("bark", (0.3, 0.2, 0.1), checker=(0.2, 0.15, 0.08))
    canopy = material("canopy", (0.15, 0.4, 0.1), checker=(0.1, 0.3, 0.05))
    for i in range(6):
        x = -0.9 + 0.35 * i + rng.uniform(-0.05, 0.05)
        trees.box(bark, (x - 0.04, 8.0, 0.0), (x + 0.04, 8.1, 1.4))
        trees.sphere(canopy, (x, 8.2, 1.4 + rng.uniform(0.0, 0.4)), 0.18 + rng.uniform(0.0, 0.1))
    return lens, 2.8, 8.0, [leaves, trees]


def strand_points(rng, x, depth, top, length, sway):
    pts, px, pz = [], x, top
    for i in range(12):
        pts.append((px, depth + rng.uniform(-0.01, 0.01), pz))
        px += sway * math.sin(i * 0.7 + x * 40.0) + rng.uniform(-0.002, 0.002)
        pz -= length / 11
    return pts


def strands_near(rng):
    """Hair-like sub-pixel strands 1.2 m away, backlit by the sky, a building in focus at
    6 m: 100 mm f/1.4 (strand CoC ~17 px)."""
    lens = 100.0
    world((8.0, 7.5, 7.0), (2.0, 3.0, 7.0), 1.5)
    sun(2.5, elevation_deg=25.0, azimuth_deg=160.0)
    hair, yard = Group("hair"), Group("yard")
    h = half_width(1.2, lens)
    fibre = material("fibre", (0.45, 0.3, 0.15), roughness=0.25)
    for _ in range(70):
        hair.tube(fibre, strand_points(rng, rng.uniform(-h, h), 1.2, EYE + h * 1.2, 2.4 * h, 0.004), 0.0004, sides=4)
    courtyard(yard, 6.0, lens, rng)
    return lens, 1.4, 6.0, [hair, yard]


def strands_in_focus(rng):
    """Strands in focus 2 m away in front of far bright lights (bokeh discs) and a wall at
    infinity-ish 30 m: 70 mm f/1.4."""
    lens = 70.0
    world((5.0, 5.0, 5.5), (1.0, 1.5, 4.0), 1.0)
    sun(2.1, elevation_deg=30.0, azimuth_deg=200.0)
    hair, lights, yard = Group("hair"), Group("lights"), Group("yard")
    h = half_width(2.0, lens)
    fibre = material("fibre", (0.6, 0.5, 0.3), roughness=0.25)
    for _ in range(50):
        hair.tube(fibre, strand_points(rng, rng.uniform(-h, h), 2.0, EYE + h * 1.2, 2.4 * h, 0.008), 0.0009, sides=4)
    bulb = material("bulb", (1.0, 0.8, 0.5), emit=40.0)
    for _ in range(14):
        lights.sphere(bulb, (rng.uniform(-4.0, 4.0), 18.0, rng.uniform(0.3, 3.5)), 0.04, rings=6, segments=10)
    courtyard(yard, 30.0, lens, rng)
    return lens, 1.4, 2.0, [hair, lights, yard]


def mast_sky(rng):
    """A thin mast and guy cables 0.5 m away over a bright sky (CoC ~9 px), hills in focus
    at 20 m: 50 mm f/2."""
    lens = 50.0
    world((9.0, 8.5, 8.0), (2.5, 3.5, 8.0), 1.5)
    sun(2.5)
    mast, hills = Group("mast"), Group("hills")
    metal = material("metal", (0.3, 0.3, 0.32), roughness=0.2)
    mast.tube(metal, [(-0.02, 0.5, EYE - 0.5), (-0.02, 0.5, EYE + 0.5)], 0.0015)
    for k in range(5):
        a = -0.2 + 0.1 * k
        mast.tube(metal, [(-0.02, 0.5, EYE + 0.1 * k - 0.1), (0.25, 0.5, EYE + a - 0.15)], 0.0007)
    mast.tube(metal, [(-0.25, 0.5, EYE + 0.12), (0.25, 0.5, EYE + 0.15)], 0.0008)
    grass = material("hill", (0.3, 0.45, 0.15), checker=(0.25, 0.35, 0.1))
    w = half_width(20.0, lens) * 1.5
    for i in range(8):
        x = -w + 2 * w * i / 8
        hills.box(grass, (x, 20.0, -1.0), (x + 2 * w / 8, 21.0, EYE - 0.4 + rng.uniform(0.0, 1.0)))
    return lens, 2.0, 20.0, [mast, hills]


def specular_near(rng):
    """Chrome balls 1.5 m away reflecting small bright lamps (highlights that must bloom),
    focus on a wall at 6 m: 85 mm f/2 (CoC ~6 px)."""
    lens = 85.0
    world((3.0, 3.0, 3.2), (1.0, 1.5, 3.0), 1.0)
    sun(1.7)
    balls, lamps, yard = Group("balls"), Group("lamps"), Group("yard")
    chrome = material("chrome", (0.8, 0.8, 0.8), roughness=0.02)
    for i in range(4):
        balls.sphere(chrome, (-0.2 + 0.13 * i, 1.5, EYE - 0.1 + 0.06 * (i % 2)), 0.04)
    lamp = material("lamp", (1.0, 0.95, 0.9), emit=200.0)
    for i in range(3):
        lamps.sphere(lamp, (-0.8 + 0.8 * i, 0.3, EYE + 0.6), 0.02, rings=6, segments=10)
    courtyard(yard, 6.0, lens, rng)
    return lens, 2.0, 6.0, [lamps, balls, yard]


def specular_far(rng):
    """A subject in focus 2 m away, glossy balls and fairy lights far behind (CoC ~15 px):
    135 mm f/2."""
    lens = 135.0
    world((3.0, 3.0, 3.5), (0.8, 1.2, 3.0), 1.0)
    sun(2.5)
    subject, far = Group("subject"), Group("far")
    subject.box(material("crate", (0.6, 0.4, 0.2), checker=(0.3, 0.2, 0.1)), (-0.12, 2.0, EYE - 0.3), (0.02, 2.15, EYE + 0.05))
    subject.tube(material("rod", (0.1, 0.1, 0.1)), [(0.06, 2.0, EYE - 0.3), (0.09, 2.0, EYE + 0.2)], 0.002)
    glossy = material("glossy", (0.2, 0.3, 0.6), roughness=0.02)
    bulb = material("fairy", (1.0, 0.85, 0.6), emit=80.0)
    for i in range(10):
        far.sphere(glossy, (rng.uniform(-1.5, 1.5), 20.0, rng.uniform(0.5, 2.5)), 0.08, rings=8, segments=16)
    for i in range(16):
        far.sphere(bulb, (-1.6 + 0.2 * i, 20.0, 2.3 + 0.2 * math.sin(i)), 0.015, rings=6, segments=10)
    courtyard(far, 24.0, lens, rng)
    return lens, 2.0, 2.0, [subject, far]


def depths_three(rng):
    """Boxes at 2, 4 and 8 m, focus on 4 m, wall at 30 m: 135 mm f/2.8."""
    lens = 135.0
    world((5.0, 5.0, 5.0), (1.5, 2.0, 5.0), 1.0)
    sun(2.5)
    groups = []
    for depth, colour in ((2.0, (0.8, 0.3, 0.2)), (4.0, (0.2, 0.6, 0.3)), (8.0, (0.2, 0.3, 0.8))):
        g = Group(f"at{int(depth)}m")
        h = half_width(depth, lens)
        x = -h + h * (0.3 if depth == 2.0 else 0.8 if depth == 4.0 else 1.3)
        g.box(material(f"box{depth}", colour, checker=(0.9, 0.9, 0.85)), (x, depth, EYE - 0.6 * h), (x + 0.5 * h, depth + 0.2, EYE + 0.4 * h))
        g.tube(material(f"pole{depth}", (0.9, 0.9, 0.9)), [(x + 0.7 * h, depth, EYE - h), (x + 0.7 * h, depth, EYE + h)], 0.0015 * depth)
        groups.append(g)
    yard = Group("yard")
    courtyard(yard, 30.0, lens, rng)
    return lens, 2.8, 4.0, groups + [yard]


def edge_crossing(rng):
    """Near objects cut by the frame: a post at the left edge 1 m away, a ball over the
    right edge at 1.5 m, a lamp on the top edge; focus 3 m: 85 mm f/1.8."""
    lens = 85.0
    world((5.0, 5.0, 5.5), (1.5, 2.0, 5.0), 1.0)
    sun(2.5)
    near, mid = Group("near"), Group("mid")
    h1, h15 = half_width(1.0, lens), half_width(1.5, lens)
    near.box(material("post", (0.3, 0.2, 0.15), checker=(0.5, 0.35, 0.2)), (-h1 - 0.03, 1.0, 0.0), (-h1 + 0.04, 1.05, 3.0))
    near.sphere(material("lamp", (1.0, 0.9, 0.8), emit=50.0), (0.05, 1.0, EYE + h1 - 0.005), 0.01, rings=6, segments=10)
    near.sphere(material("ball", (0.7, 0.7, 0.75), roughness=0.05), (h15 + 0.05, 1.5, EYE - 0.1), 0.12)
    mid.box(material("sign", (0.9, 0.8, 0.2), checker=(0.1, 0.1, 0.1)), (-0.4, 3.0, EYE - 0.4), (0.3, 3.05, EYE + 0.2))
    yard = Group("yard")
    courtyard(yard, 14.0, lens, rng)
    return lens, 1.8, 3.0, [near, mid, yard]


def deep_f8(rng):
    """f/8 at 135 mm focused 10 m: a fence 3 m away blurred ~2 px, nearly everything sharp
    (a method must not damage what barely needs blurring)."""
    lens = 135.0
    world((5.0, 5.0, 5.5), (1.5, 2.5, 5.5), 1.2)
    sun(2.5)
    fence, yard = Group("fence"), Group("yard")
    h = half_width(3.0, lens) * 1.2
    grid(fence, material("wire", (0.3, 0.3, 0.3), roughness=0.3), 3.0, h, EYE - h, EYE + h, 0.05, 0.0015)
    courtyard(yard, 10.0, lens, rng)
    return lens, 8.0, 10.0, [fence, yard]


SCENES = {
    "fence-near-hdr": fence_near_hdr,
    "fence-far-focus-near": fence_far_focus_near,
    "fence-near-135": fence_near_135,
    "grid-near": grid_near,
    "foliage-holes": foliage_holes,
    "strands-near": strands_near,
    "strands-in-focus": strands_in_focus,
    "mast-sky": mast_sky,
    "specular-near": specular_near,
    "specular-far": specular_far,
    "depths-three": depths_three,
    "edge-crossing": edge_crossing,
    "deep-f8": deep_f8,
}


# --- procedural scenes (issue 46) -------------------------------------------------------
# A scene named "<split>-<index>" (split "dev" or "test") is drawn from a seed: its family
# (index modulo FAMILIES, so every family is in both splits), then placement, wire gauge and
# spacing, lens 35-135 mm, f-stop 1.4-8 and one of the HDR worlds Blender ships. The dev set
# is for tuning; the test set is scored only for a candidate one would ship.

WORLDS = ["city", "courtyard", "forest", "interior", "night", "studio", "sunrise", "sunset"]


def hdri_world(rng, name, strength):
    """One of Blender's studio-light HDRIs, turned at random, times `strength` (see `seen_sky`)."""
    folder = bpy.utils.system_resource("DATAFILES", path="studiolights/world")
    nodes, links = new_world()
    coords = nodes.new("ShaderNodeTexCoord")
    turn = nodes.new("ShaderNodeMapping")
    turn.inputs["Rotation"].default_value = (0.0, 0.0, rng.uniform(0.0, 2.0 * math.pi))
    env = nodes.new("ShaderNodeTexEnvironment")
    env.image = bpy.data.images.load(os.path.join(folder, name + ".exr"))
    links.new(coords.outputs["Generated"], turn.inputs["Vector"])
    links.new(turn.outputs["Vector"], env.inputs["Vector"])
    seen_sky(nodes, links, env.outputs["Color"], strength)


def random_colour(rng, lo=0.1, hi=0.85):
    return (rng.uniform(lo, hi), rng.uniform(lo, hi), rng.uniform(lo, hi))


def city_lights(group, rng, depth, lens, count):
    """Small bright lamps scattered over the frame at about `depth` (bokeh discs when blurred)."""
    h = half_width(depth, lens)
    bulbs = [material(f"lamp{i}", (1.0, rng.uniform(0.6, 1.0), rng.uniform(0.3, 0.9)), emit=rng.uniform(30.0, 120.0)) for i in range(3)]
    for _ in range(count):
        d = depth * rng.uniform(0.9, 1.2)
        group.sphere(rng.choice(bulbs), (rng.uniform(-h, h) * 1.1, d, EYE + rng.uniform(-h, h)), 0.004 * d * 50.0 / lens,
                     rings=6, segments=10)


def backdrop(group, rng, depth, lens, night):
    """A city block or a courtyard at `depth`: the in-focus or blurred far structure."""
    if night:
        h = half_width(depth, lens) * 1.6
        for i in range(8):
            x = -h + 2 * h * i / 8
            top = EYE + rng.uniform(-0.5, 1.0) * half_width(depth, lens)
            group.box(material(f"tower{i}", random_colour(rng, 0.05, 0.3), checker=random_colour(rng, 0.02, 0.15)),
                      (x, depth + rng.uniform(0.0, 2.0), -1.0), (x + 2 * h / 8 * 0.9, depth + 3.0, top))
        city_lights(group, rng, depth * 0.95, lens, rng.randint(10, 30))
    else:
        courtyard(group, depth, lens, rng)


def proc_fence(rng, lens, fstop, fence_in_focus):
    """Failure cases 1 and 3 of issue 46: a wire fence over a far backdrop, the fence in
    focus over blurred city lights or blurred over an in-focus, lit backdrop with a bright
    bead on a wire."""
    near = rng.uniform(0.8, 2.5)
    far = rng.uniform(8.0, 25.0)
    fence, back = Group("fence"), Group("back")
    h = half_width(near, lens) * 1.3
    px = 2.0 * half_width(near, lens) / 256.0  # metres per pixel at the fence
    radius = px * rng.uniform(0.35, 1.0)
    spacing = px * rng.uniform(8.0, 24.0)
    wire = material("wire", random_colour(rng, 0.15, 0.7), roughness=rng.uniform(0.1, 0.5))
    if rng.random() < 0.5:
        diagonal_fence(fence, wire, near, h, EYE - h, EYE + h, spacing, radius, rng.uniform(25.0, 65.0))
    else:
        grid(fence, wire, near, h, EYE - h, EYE + h, spacing, radius)
    night = fence_in_focus and rng.random() < 0.8
    backdrop(back, rng, far, lens, night)
    if not fence_in_focus:
        for _ in range(rng.randint(1, 3)):
            fence.sphere(material("bead", (1.0, 0.9, 0.7), emit=rng.uniform(30.0, 80.0)),
                         (rng.uniform(-0.5, 0.5) * half_width(near, lens), near - 0.01, EYE + rng.uniform(-0.5, 0.5) * half_width(near, lens)),
                         radius * 2.5, rings=6, segments=10)
    return (near if fence_in_focus else far), [fence, back], ("night" if night else rng.choice(["courtyard", "sunrise", "sunset", "forest"]))


def proc_silhouette(rng, lens, fstop):
    """Failure case 2: an in-focus round silhouette (a head, a vase) over a blurred night city."""
    near = rng.uniform(1.0, 3.0)
    far = rng.uniform(10.0, 30.0)
    subject, back = Group("subject"), Group("back")
    h = half_width(near, lens)
    r = h * rng.uniform(0.25, 0.5)
    cx = rng.uniform(-0.4, 0.4) * h
    subject.sphere(material("skin", random_colour(rng, 0.2, 0.8), checker=random_colour(rng, 0.1, 0.6)), (cx, near, EYE + rng.uniform(-0.3, 0.1) * h), r, rings=24, segments=48)
    subject.box(material("body", random_colour(rng, 0.05, 0.5)), (cx - 1.3 * r, near, EYE - 3.0 * h), (cx + 1.3 * r, near + 0.3, EYE - 0.2 * h - r * 0.8))
    backdrop(back, rng, far, lens, True)
    return near, [subject, back], "night"


def proc_foliage(rng, lens, fstop):
    near, far = rng.uniform(1.5, 4.0), rng.uniform(6.0, 20.0)
    leaves, back = Group("leaves"), Group("back")
    h = half_width(near, lens) * 1.2
    greens = [material(f"leaf{i}", (0.05 + 0.1 * i, 0.3 + 0.1 * i, 0.05)) for i in range(3)]
    holes = [(rng.uniform(-h, h), EYE + rng.uniform(-h, h), rng.uniform(0.05, 0.2) * h) for _ in range(rng.randint(2, 6))]
    for _ in range(int(1500 * rng.uniform(0.5, 1.0))):
        cx, cz = rng.uniform(-h, h), EYE + rng.uniform(-h, h)
        if any((cx - x) ** 2 + (cz - z) ** 2 < r * r for x, z, r in holes):
            continue
        size, turn = rng.uniform(0.02, 0.06) * h, rng.uniform(0.0, math.pi)
        pts = [(cx + size * math.cos(turn + a) * (1.0 if k % 2 == 0 else 0.5), near + rng.uniform(-0.05, 0.05),
                cz + size * math.sin(turn + a) * (1.0 if k % 2 == 0 else 0.5))
               for k, a in enumerate([0.0, math.pi / 2, math.pi, 3 * math.pi / 2])]
        leaves.quad(rng.choice(greens), pts)
    backdrop(back, rng, far, lens, rng.random() < 0.3)
    focus = near if rng.random() < 0.4 else far
    return focus, [leaves, back], rng.choice(["forest", "courtyard", "sunrise"])


def proc_strands(rng, lens, fstop):
    near, far = rng.uniform(1.0, 3.0), rng.uniform(5.0, 25.0)
    hair, back = Group("hair"), Group("back")
    h = half_width(near, lens)
    px = 2.0 * h / 256.0
    fibre = material("fibre", random_colour(rng, 0.2, 0.7), roughness=0.25)
    for _ in range(rng.randint(30, 80)):
        hair.tube(fibre, strand_points(rng, rng.uniform(-h, h), near, EYE + h * 1.2, 2.4 * h, px * rng.uniform(1.0, 4.0)), px * rng.uniform(0.2, 0.6), sides=4)
    night = rng.random() < 0.5
    backdrop(back, rng, far, lens, night)
    focus = near if rng.random() < 0.5 else far
    return focus, [hair, back], ("night" if night else rng.choice(["courtyard", "sunset", "city"]))


def proc_planes(rng, lens, fstop):
    """Three to five textured planes at spread depths (the held-out five-planes case)."""
    count = rng.randint(3, 5)
    depths = sorted(rng.uniform(1.0, 20.0) for _ in range(count))
    groups = []
    for i, depth in enumerate(depths):
        g = Group(f"plane{i}")
        h = half_width(depth, lens)
        x = rng.uniform(-1.0, 0.6) * h
        z = EYE + rng.uniform(-1.0, 0.4) * h
        g.box(material(f"plane{i}", random_colour(rng), checker=random_colour(rng)), (x, depth, z), (x + rng.uniform(0.3, 0.9) * h, depth + 0.05, z + rng.uniform(0.3, 0.9) * h))
        if rng.random() < 0.5:
            g.sphere(material(f"spot{i}", (1.0, 0.9, 0.8), emit=rng.uniform(20.0, 80.0)), (x, depth - 0.02, z), 0.004 * depth * 50.0 / lens, rings=6, segments=10)
        groups.append(g)
    back = Group("back")
    backdrop(back, rng, rng.uniform(25.0, 40.0), lens, rng.random() < 0.3)
    focus = rng.choice(depths + [30.0])
    return focus, groups + [back], rng.choice(WORLDS)


FAMILIES = [
    ("fence-in-focus", lambda rng, lens, fstop: proc_fence(rng, lens, fstop, True)),
    ("fence-blurred", lambda rng, lens, fstop: proc_fence(rng, lens, fstop, False)),
    ("silhouette", proc_silhouette),
    ("foliage", proc_foliage),
    ("strands", proc_strands),
    ("planes", proc_planes),
]
SPLITS = ("dev", "test")


def procedural(name):
    """The scene builder for "<split>-<index>": a family by index, the rest from the name's
    seed. Returns the builder in the (lens, f-stop, focus, groups) form of SCENES."""
    split, index = name.rsplit("-", 1)
    family, make = FAMILIES[int(index) % len(FAMILIES)]

    def build_scene(rng):
        lens = math.exp(rng.uniform(math.log(35.0), math.log(135.0)))
        fstop = math.exp(rng.uniform(math.log(1.4), math.log(8.0)))
        focus, groups, sky = make(rng, lens, fstop)
        hdri_world(rng, sky, rng.uniform(0.8, 2.0))
        if sky not in ("night", "interior", "studio"):
            sun(rng.uniform(1.5, 3.0), rng.uniform(20.0, 60.0), rng.uniform(0.0, 360.0))
        return lens, fstop, focus, groups

    build_scene.family = family
    return build_scene


def scene_builder(name):
    if name in SCENES:
        return SCENES[name]
    split, _, index = name.rpartition("-")
    if split in SPLITS and index.isdigit():
        return procedural(name)
    raise SystemExit(f"unknown scene {name!r}; known: {list(SCENES)} and dev-N / test-N")


# --- rendering --------------------------------------------------------------------------

def setup(size):
    bpy.ops.wm.read_factory_settings(use_empty=True)
    scene = bpy.context.scene
    scene.render.engine = "CYCLES"
    c = scene.cycles
    c.device = "CPU"
    c.use_denoising = False
    c.use_adaptive_sampling = False
    c.seed = 1
    # Direct light, mirror-like reflections and no diffuse interreflection: the truth's
    # noise must stay well under the methods' differences (with one diffuse bounce the
    # pinhole input and the truth differed by 29 dB on an in-focus wall at 128^2, 256 spp).
    c.max_bounces, c.diffuse_bounces, c.glossy_bounces = 2, 0, 1
    c.blur_glossy = 1.0
    c.transmission_bounces, c.volume_bounces, c.transparent_max_bounces = 0, 0, 8
    c.caustics_reflective = c.caustics_refractive = False
    scene.render.resolution_x = scene.render.resolution_y = size
    scene.render.resolution_percentage = 100
    scene.view_settings.view_transform = "Standard"
    return scene


def render(scene, path, samples, layers, transparent, dof, multilayer):
    scene.cycles.samples = samples
    scene.render.film_transparent = transparent
    scene.camera.data.dof.use_dof = dof
    for vl in scene.view_layers:
        vl.use = vl.name in layers
    settings = scene.render.image_settings
    settings.file_format = "OPEN_EXR_MULTILAYER" if multilayer else "OPEN_EXR"
    settings.color_mode, settings.color_depth, settings.exr_codec = "RGBA", "32", "ZIP"
    scene.render.filepath = path
    bpy.ops.render.render(write_still=True)


def build(name, params, out_dir):
    start = time.perf_counter()
    scene = setup(params["size"])
    rng = random.Random(name)
    builder = scene_builder(name)
    lens, fstop, focus, groups = builder(rng)
    for g in groups:
        g.build()
    cam_data = bpy.data.cameras.new("Camera")
    cam_data.lens, cam_data.sensor_width, cam_data.sensor_fit = lens, SENSOR, "HORIZONTAL"
    cam_data.dof.aperture_fstop, cam_data.dof.focus_distance = fstop, focus
    cam_data.dof.aperture_blades = 0
    cam_data.clip_start, cam_data.clip_end = 0.05, 1000.0
    cam = bpy.data.objects.new("Camera", cam_data)
    cam.location = (0.0, 0.0, EYE)
    cam.rotation_euler = (math.pi / 2, 0.0, 0.0)
    scene.collection.objects.link(cam)
    scene.camera = cam

    first = scene.view_layers[0]
    first.name = "All"
    layers = {"All": first}
    for vl_name in ["Sky"] + [g.name for g in groups]:
        layers[vl_name] = scene.view_layers.new(vl_name)
    for vl_name, vl in layers.items():
        vl.use_pass_z = True
        for g in groups:
            vl.layer_collection.children[g.name].exclude = vl_name not in ("All", g.name)
    folder = os.path.join(out_dir, name)
    os.makedirs(folder, exist_ok=True)
    render(scene, os.path.join(folder, "truth.exr"), params["truth_spp"], ["All"], False, True, False)
    render(scene, os.path.join(folder, "pinhole.exr"), params["pinhole_spp"], ["All", "Sky"], False, False, True)
    render(scene, os.path.join(folder, "layers.exr"), params["layer_spp"], [g.name for g in groups], True, False, True)
    info = {
        "name": name, "focal_length_mm": lens, "sensor_width_mm": SENSOR, "fstop": fstop,
        "focus_distance": focus, "size": params["size"], "groups": [g.name for g in groups],
        "truth_spp": params["truth_spp"], "pinhole_spp": params["pinhole_spp"], "layer_spp": params["layer_spp"],
        "seconds": time.perf_counter() - start, "blender": bpy.app.version_string,
        "family": getattr(builder, "family", name),
    }
    with open(os.path.join(folder, "camera.json"), "w") as f:
        json.dump(info, f, indent=1)
    print("LENSBLUR_CYCLES " + name + " " + json.dumps(info), flush=True)


def main():
    args = sys.argv[sys.argv.index("--") + 1:]
    out_dir, params = args[0], json.loads(args[1])
    names = params.get("scenes") or list(SCENES)
    for name in names:
        scene_builder(name)  # refuses an unknown name before anything renders
    for name in names:
        build(name, params, out_dir)


main()
