"""
The marker sphere as a fine icosphere mesh (Wavefront OBJ), pure Python.

PyBullet draws a URDF ``<sphere>`` with a coarse polygon whose outline moves the image
centre by up to 0.15 px as joint 6 turns (measured); :mod:`ibvs_model.urdf` refers to this
mesh instead, scaled to the marker radius.
"""

import math

import numpy as np

#: File name of the marker sphere mesh (unit radius), written beside the URDF.
MARKER_MESH = 'marker_sphere.obj'
#: Subdivisions of the icosahedron: 4 gives 5120 faces, edges of about 4 degrees of arc.
MARKER_MESH_SUBDIVISIONS = 4


def icosphere_obj(subdivisions: int = MARKER_MESH_SUBDIVISIONS) -> str:
    """
    Return a Wavefront OBJ of the unit sphere: an icosahedron subdivided ``subdivisions`` times.

    Each subdivision splits every triangle into four, with the new vertices pushed out to
    the sphere; the vertex normals are the vertex positions (smooth shading). The faces are
    20 * 4^subdivisions, wound counter-clockwise seen from outside.

    Parameters
    ----------
    subdivisions : int
        In [0, 6].

    Returns
    -------
    str
        The OBJ text.

    """
    if not (isinstance(subdivisions, int) and 0 <= subdivisions <= 6):
        raise ValueError(f'subdivisions must be an int in [0, 6], got {subdivisions!r}')
    t = (1.0 + math.sqrt(5.0)) / 2.0
    vertices = [np.array(v, float) / math.hypot(1.0, t) for v in (
        (-1, t, 0), (1, t, 0), (-1, -t, 0), (1, -t, 0), (0, -1, t), (0, 1, t),
        (0, -1, -t), (0, 1, -t), (t, 0, -1), (t, 0, 1), (-t, 0, -1), (-t, 0, 1))]
    faces = [(0, 11, 5), (0, 5, 1), (0, 1, 7), (0, 7, 10), (0, 10, 11), (1, 5, 9),
             (5, 11, 4), (11, 10, 2), (10, 7, 6), (7, 1, 8), (3, 9, 4), (3, 4, 2),
             (3, 2, 6), (3, 6, 8), (3, 8, 9), (4, 9, 5), (2, 4, 11), (6, 2, 10),
             (8, 6, 7), (9, 8, 1)]
    for _ in range(subdivisions):
        midpoints = {}

        def midpoint(a, b):
            key = (min(a, b), max(a, b))
            if key not in midpoints:
                m = vertices[a] + vertices[b]
                vertices.append(m / np.linalg.norm(m))
                midpoints[key] = len(vertices) - 1
            return midpoints[key]

        refined = []
        for a, b, c in faces:
            ab, bc, ca = midpoint(a, b), midpoint(b, c), midpoint(c, a)
            refined += [(a, ab, ca), (b, bc, ab), (c, ca, bc), (ab, bc, ca)]
        faces = refined
    lines = [f'# Unit icosphere, {len(faces)} faces: ibvs_model.mesh.icosphere_obj'
             f'({subdivisions}).']
    lines += ['v {:.6f} {:.6f} {:.6f}'.format(*v) for v in vertices]
    lines += ['vn {:.6f} {:.6f} {:.6f}'.format(*v) for v in vertices]
    lines += [f'f {a + 1}//{a + 1} {b + 1}//{b + 1} {c + 1}//{c + 1}' for a, b, c in faces]
    return '\n'.join(lines) + '\n'
