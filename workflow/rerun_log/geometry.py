"""MuJoCo geoms as Rerun shapes: boxes, planes, spheres, ellipsoids, capsules, cylinders and
meshes, coloured from geom_rgba (or the material's)."""
from __future__ import annotations

import mujoco
import numpy as np
import rerun as rr

from .arrow import entity_part

_G = mujoco.mjtGeom
_PLANE_HALF_M = 2.0  # half size drawn for an infinite (size 0) plane
_DEFAULT_RGBA = (0.5, 0.5, 0.5, 1.0)  # MuJoCo's geom rgba default: the material's colour wins


def drawn_geoms(m: mujoco.MjModel, body_paths: list[str]):
    """(geom id, entity path, archetype) of every geom drawn: visual geoms (groups 0-2), and
    collision geoms only on bodies that have no visual one; transparent geoms are skipped."""
    group = np.asarray(m.geom_group)
    has_visual = np.zeros(m.nbody, bool)
    for g in range(m.ngeom):
        if group[g] < 3 and m.geom_rgba[g, 3] > 0:
            has_visual[m.geom_bodyid[g]] = True
    for g in range(m.ngeom):
        b = m.geom_bodyid[g]
        if group[g] >= 3 and has_visual[b]:
            continue
        rgba = np.array(m.geom_rgba[g])
        if m.geom_matid[g] >= 0 and np.allclose(rgba, _DEFAULT_RGBA):
            rgba = np.array(m.mat_rgba[m.geom_matid[g]])
        if rgba[3] <= 0:
            continue
        shape = geom_shape(m, g, rgba)
        if shape is not None:
            yield g, f"{body_paths[b]}/{entity_part(m.geom(g).name or f'geom{g}')}", shape

def geom_shape(m: mujoco.MjModel, g: int, rgba):
    """The Rerun archetype drawing geom ``g`` in its own frame, or None (height fields, SDFs)."""
    t, s = int(m.geom_type[g]), m.geom_size[g]
    color = [np.clip(np.round(np.asarray(rgba) * 255), 0, 255).astype(np.uint8)]
    solid = rr.components.FillMode.Solid
    if t == _G.mjGEOM_BOX:
        return rr.Boxes3D(half_sizes=[s], colors=color, fill_mode=solid)
    if t == _G.mjGEOM_PLANE:
        hx, hy = (s[0] or _PLANE_HALF_M), (s[1] or _PLANE_HALF_M)
        return rr.Boxes3D(half_sizes=[[hx, hy, 5e-4]], centers=[[0, 0, -5e-4]], colors=color, fill_mode=solid)
    if t == _G.mjGEOM_SPHERE:
        return rr.Ellipsoids3D(half_sizes=[[s[0]] * 3], colors=color, fill_mode=solid)
    if t == _G.mjGEOM_ELLIPSOID:
        return rr.Ellipsoids3D(half_sizes=[s], colors=color, fill_mode=solid)
    if t == _G.mjGEOM_CAPSULE:  # Rerun's capsule starts at its origin and runs along +z
        return rr.Capsules3D(lengths=[2 * s[1]], radii=[s[0]], translations=[[0, 0, -s[1]]], colors=color)
    if t == _G.mjGEOM_CYLINDER:
        return rr.Cylinders3D(lengths=[2 * s[1]], radii=[s[0]], colors=color, fill_mode=solid)
    if t == _G.mjGEOM_MESH and m.geom_dataid[g] >= 0:
        k = m.geom_dataid[g]
        v0, nv = m.mesh_vertadr[k], m.mesh_vertnum[k]
        f0, nf = m.mesh_faceadr[k], m.mesh_facenum[k]
        verts = np.array(m.mesh_vert[v0:v0 + nv])
        faces = np.array(m.mesh_face[f0:f0 + nf])
        return rr.Mesh3D(vertex_positions=verts, triangle_indices=faces,
                         vertex_normals=vertex_normals(verts, faces), albedo_factor=color[0])
    return None  # height fields, SDFs: not drawn


def vertex_normals(verts: np.ndarray, faces: np.ndarray) -> np.ndarray:
    """Unit vertex normals of a triangle mesh: the area-weighted sum of its faces' normals."""
    n = np.zeros_like(verts)
    if len(faces):
        a, b, c = verts[faces[:, 0]], verts[faces[:, 1]], verts[faces[:, 2]]
        fn = np.cross(b - a, c - a)
        for k in range(3):
            np.add.at(n, faces[:, k], fn)
    norm = np.linalg.norm(n, axis=1, keepdims=True)
    return n / np.where(norm > 0, norm, 1.0)
