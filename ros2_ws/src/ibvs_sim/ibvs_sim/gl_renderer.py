"""
A renderer of our own: the world's visual shapes drawn with OpenGL (moderngl), no PyBullet.

The simulator's renderer (:class:`ibvs_sim.rendering.Renderer`). PyBullet's own renderers
are not used: its EGL plugin spends 5-9 ms of every ``getCameraImage`` call on llvmpipe in
a shadow-map pass that no argument reaches, however small the image, and the same
triangles drawn directly cost a fraction of that (docs/speed.md).

Device (:func:`device_order`). The context is opened once, at construction, on an EGL
device: a GPU's when the EGL library lists one and a context opens on it, Mesa's software
rasteriser (llvmpipe) otherwise; :attr:`GLRenderer.device` says which
(:class:`ibvs_sim.rendering.RenderDevice`), and the simulator reports it in the run's
metrics (``render_device``, ``render_hardware``). ``GLCONTEXT_DEVICE_INDEX`` (glcontext's
variable) pins one device index. A GPU and llvmpipe may round an edge pixel differently:
runs compare to the bit on one device.

What it draws. :class:`GLRenderer` is given the scene once, as :class:`Shape` s: triangles
(positions and normals in the frame of a *part*, e.g. a robot link), a colour, and the part
they move with. Each :meth:`GLRenderer.render` is given the pose of every part (from PyBullet,
:class:`ibvs_sim.world.World`), a view matrix and pinhole intrinsics, and returns the RGB
image. The camera is :mod:`ibvs_sim.rendering`'s: the projection of
:func:`ibvs_sim.rendering.projection_matrix`, under which OpenGL's rasteriser, which samples
pixel (i, j) of the window at (i + 1/2, j + 1/2), samples image pixel (i, j) exactly at
u = i, v = j, the pixel convention of :mod:`ibvs_model.camera` (eq. 16-22). OpenGL's window
rows run bottom-up; the projection's y is negated so that window row j is image row v = j
and the read-back needs no flip; the flip reverses the winding on screen, so the front
faces (counter-clockwise seen from outside, :class:`Shape`) are the clockwise ones there,
and the back faces are culled (every shape is closed but the one-sided ground, seen from
above only: measured 28 instead of 34 ms a pass at HD720, loaded machine; 2 pixels of
921600 change, where two solids of a link overlap and the depth test had a tie). Depth test
on the depth buffer between the clipping planes of that projection.

Lighting: that of PyBullet's former EGL plugin (bullet3's useShadowMapInstancing shaders)
without its shadows: a directional light towards ``light_direction`` (the simulator's:
:data:`ibvs_sim.world.LIGHT_DIRECTION`), intensity
i = 1/2 + 1/2 clamp(n . l, -1, 1), times 0.7 on faces turned away from the light, and the
colour rgb (1/2 + i/2); no specular highlight. The robot casts no shadow on the ground.
Computed once a pixel from the interpolated normal, but once a vertex for the flat shapes
(boxes, the ground), whose pixels would all interpolate the vertices' one normal.

Cost: a pass draws only the shapes that can reach its pixels, and none that the caller
paints over (:meth:`GLRenderer.render`); a stereo pair's passes are drawn together
(:meth:`GLRenderer.render_passes`). docs/speed.md has the measurements.

Determinism: one context, fixed geometry, no blending or multisampling; one device
rasterises the same triangles to the same pixels every time (tested to the bit on llvmpipe).
"""

from collections.abc import Sequence
import contextlib
import ctypes
from dataclasses import dataclass
import math
import os

import cv2
import numpy as np
from numpy.typing import ArrayLike, NDArray

from .rendering import Pass, RenderDevice

#: Background colour: PyBullet's former EGL plugin's (measured: 178, 178, 204 of 255).
BACKGROUND_RGB = (0.7, 0.7, 0.8)
#: Facets of a cylinder's side: a chord deviates 0.1 % of the radius from the circle.
CYLINDER_SEGMENTS = 64
#: The most parts (rigid bodies or links) one scene may hold (size of the shader's arrays).
MAX_PARTS = 32

#: The lighting (module docstring) of a normal in {O}, both programs' (one rule).
_LIGHTING = """
uniform vec3 light;
vec3 lit(vec3 normal, vec3 rgb) {
    float cosine = dot(normalize(normal), light);
    float intensity = 0.5 + 0.5 * clamp(cosine, -1.0, 1.0);
    if (cosine < 0.0) {
        intensity *= 0.7;
    }
    return rgb * (0.5 + 0.5 * intensity);
}
"""

_VERTEX_SHADER = """
#version 330
uniform mat4 mvp[%(parts)d];
uniform mat3 rotation[%(parts)d];
in vec3 in_position;
in vec3 in_normal;
in vec3 in_colour;
in int in_part;
out vec3 v_normal;
flat out vec3 v_colour;
void main() {
    gl_Position = mvp[in_part] * vec4(in_position, 1.0);
    v_normal = rotation[in_part] * in_normal;
    v_colour = in_colour;
}
"""

_FRAGMENT_SHADER = """
#version 330
%(lighting)s
in vec3 v_normal;
flat in vec3 v_colour;
out vec4 colour;
void main() {
    colour = vec4(lit(v_normal, v_colour), 1.0);
}
"""

#: The program of the flat shapes (each triangle's three normals equal): the same light,
#: computed once a vertex instead of once a pixel (:meth:`GLRenderer._upload`).
_FLAT_VERTEX_SHADER = """
#version 330
uniform mat4 mvp[%(parts)d];
uniform mat3 rotation[%(parts)d];
%(lighting)s
in vec3 in_position;
in vec3 in_normal;
in vec3 in_colour;
in int in_part;
flat out vec3 v_rgb;
void main() {
    gl_Position = mvp[in_part] * vec4(in_position, 1.0);
    v_rgb = lit(rotation[in_part] * in_normal, in_colour);
}
"""

_FLAT_FRAGMENT_SHADER = """
#version 330
flat in vec3 v_rgb;
out vec4 colour;
void main() {
    colour = vec4(v_rgb, 1.0);
}
"""


class GLRendererError(RuntimeError):
    """No OpenGL context can be created here, or the scene cannot be drawn."""


#: The extension by which Mesa marks its software device (llvmpipe) among the EGL devices.
SOFTWARE_DEVICE = 'EGL_MESA_device_software'
#: GL_RENDERER names of software rasterisers (Mesa's).
SOFTWARE_RENDERERS = ('llvmpipe', 'softpipe', 'swrast')
#: glcontext's variable that pins the EGL device index (it wins over the argument).
DEVICE_INDEX_VARIABLE = 'GLCONTEXT_DEVICE_INDEX'
_EGL_EXTENSIONS = 0x3055
_MAX_DEVICES = 32


@dataclass(frozen=True)
class EGLDevice:
    """One device that EGL lists (eglQueryDevicesEXT): its index and its extensions."""

    index: int
    extensions: frozenset

    @property
    def software(self) -> bool:
        """Return whether this is Mesa's software device."""
        return SOFTWARE_DEVICE in self.extensions


def egl_devices() -> list[EGLDevice]:
    """
    Return the EGL devices of this machine, in EGL's order (glcontext's device indices).

    Empty where libEGL or its device enumeration (EGL_EXT_device_enumeration) is missing.
    """
    try:
        egl = ctypes.CDLL('libEGL.so.1')
    except OSError:
        return []
    egl.eglGetProcAddress.restype = ctypes.c_void_p
    egl.eglGetProcAddress.argtypes = [ctypes.c_char_p]
    query, string = (egl.eglGetProcAddress(name) for name in
                     (b'eglQueryDevicesEXT', b'eglQueryDeviceStringEXT'))
    if not query or not string:
        return []
    query = ctypes.CFUNCTYPE(ctypes.c_uint, ctypes.c_int, ctypes.POINTER(ctypes.c_void_p),
                             ctypes.POINTER(ctypes.c_int))(query)
    string = ctypes.CFUNCTYPE(ctypes.c_char_p, ctypes.c_void_p, ctypes.c_int)(string)
    handles, count = (ctypes.c_void_p * _MAX_DEVICES)(), ctypes.c_int()
    if not query(_MAX_DEVICES, handles, ctypes.byref(count)):
        return []
    return [EGLDevice(i, frozenset((string(handles[i], _EGL_EXTENSIONS) or b'').decode()
                                   .split())) for i in range(count.value)]


def device_order(devices: Sequence[EGLDevice]) -> list[int | None]:
    """
    Return the device indices to try a context on, first to last.

    The hardware devices (GPUs) in EGL's order, then the software ones; ``[None]`` (EGL's
    default display) where none is listed.
    """
    ordered = sorted(devices, key=lambda d: (d.software, d.index))
    return [d.index for d in ordered] or [None]


def is_hardware(gl_renderer: str) -> bool:
    """Return whether a GL_RENDERER string names a GPU (not a software rasteriser)."""
    name = gl_renderer.lower()
    return not any(soft in name for soft in SOFTWARE_RENDERERS)


@dataclass(frozen=True)
class Shape:
    """
    Triangles that move with one part: ``positions`` and ``normals`` (3 n, 3) in its frame.

    Every three rows are one triangle, counter-clockwise seen from outside; ``rgb`` in [0, 1].
    """

    part: int
    positions: np.ndarray
    normals: np.ndarray
    rgb: tuple


def box_triangles(half_extents: ArrayLike
                  ) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
    """Return (positions, normals) (36, 3) of a box centred on its frame: flat faces."""
    h = np.asarray(half_extents, dtype=float)
    positions, normals = [], []
    for axis in range(3):
        for sign in (-1.0, 1.0):
            n = np.zeros(3)
            n[axis] = sign
            a, b = (axis + 1) % 3, (axis + 2) % 3
            if sign < 0:
                a, b = b, a  # keep the winding counter-clockwise seen from outside
            ea, eb = np.zeros(3), np.zeros(3)
            ea[a], eb[b] = h[a], h[b]
            centre = n * h
            quad = [centre - ea - eb, centre + ea - eb, centre + ea + eb, centre - ea + eb]
            positions += [quad[0], quad[1], quad[2], quad[0], quad[2], quad[3]]
            normals += [n] * 6
    return np.array(positions), np.array(normals)


def cylinder_triangles(radius: float, length: float, segments: int = CYLINDER_SEGMENTS
                       ) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
    """
    Return (positions, normals) of a closed cylinder along z, centred on its frame.

    The side is smooth-shaded (normals radial), the two caps flat.
    """
    angles = np.linspace(0.0, 2.0 * math.pi, segments + 1)
    rim = np.stack([np.cos(angles), np.sin(angles), np.zeros_like(angles)], axis=1)
    top, bottom = np.array([0.0, 0.0, length / 2.0]), np.array([0.0, 0.0, -length / 2.0])
    up, down = np.array([0.0, 0.0, 1.0]), np.array([0.0, 0.0, -1.0])
    positions, normals = [], []
    for i in range(segments):
        a, b = rim[i], rim[i + 1]
        pa_top, pb_top = radius * a + top, radius * b + top
        pa_bot, pb_bot = radius * a + bottom, radius * b + bottom
        positions += [pa_bot, pb_bot, pb_top, pa_bot, pb_top, pa_top]
        normals += [a, b, b, a, b, a]
        positions += [top, pa_top, pb_top]
        normals += [up] * 3
        positions += [bottom, pb_bot, pa_bot]
        normals += [down] * 3
    return np.array(positions), np.array(normals)


def obj_triangles(text: str, scale: ArrayLike = (1.0, 1.0, 1.0)
                  ) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
    """
    Return (positions, normals) of a Wavefront OBJ's triangles, positions scaled per axis.

    Reads ``v``, ``vn`` and triangular ``f`` lines (``v``, ``v//vn`` or ``v/vt/vn``); a face
    without normals gets its flat normal. This is the subset the simulator's meshes use
    (:func:`ibvs_model.mesh.icosphere_obj`, :func:`ibvs_sim.rendering.ground_obj`).
    """
    vertices, vnormals, faces = [], [], []
    for line in text.splitlines():
        fields = line.split()
        if not fields:
            continue
        if fields[0] == 'v':
            vertices.append([float(x) for x in fields[1:4]])
        elif fields[0] == 'vn':
            vnormals.append([float(x) for x in fields[1:4]])
        elif fields[0] == 'f':
            if len(fields) != 4:
                raise GLRendererError(f'only triangles are supported, got {line!r}')
            corners = []
            for field in fields[1:]:
                parts = field.split('/')
                vn = int(parts[2]) - 1 if len(parts) == 3 and parts[2] else None
                corners.append((int(parts[0]) - 1, vn))
            faces.append(corners)
    scale = np.asarray(scale, dtype=float)
    vertices = np.asarray(vertices, dtype=float) * scale
    vnormals = np.asarray(vnormals, dtype=float) / scale if vnormals else np.zeros((0, 3))
    positions, normals = [], []
    for corners in faces:
        tri = vertices[[c[0] for c in corners]]
        if any(c[1] is None for c in corners):
            flat = np.cross(tri[1] - tri[0], tri[2] - tri[0])
            tri_normals = [flat] * 3
        else:
            tri_normals = list(vnormals[[c[1] for c in corners]])
        positions += list(tri)
        normals += tri_normals
    normals = np.asarray(normals, dtype=float)
    lengths = np.linalg.norm(normals, axis=1, keepdims=True)
    return np.asarray(positions, dtype=float), normals / np.where(lengths > 0.0, lengths, 1.0)


def transformed(positions: NDArray[np.float64], normals: NDArray[np.float64],
                transform: ArrayLike) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
    """Return (positions, normals) moved by the rigid 4x4 ``transform``."""
    tf = np.asarray(transform, dtype=float)
    return positions @ tf[:3, :3].T + tf[:3, 3], normals @ tf[:3, :3].T


class GLRenderer:
    """
    Draw fixed :class:`Shape` s moved by their parts' poses on a standalone EGL context.

    The :class:`ibvs_sim.rendering.Renderer` of the simulator. ``shapes``: the scene; parts
    are numbered 0 .. P - 1 (P <= MAX_PARTS). ``near``, ``far``: the clipping planes of
    :func:`ibvs_sim.rendering.projection_matrix`; ``light_direction``: towards the light, in
    {O}. ``devices``: the EGL devices to choose from (default :func:`egl_devices`), tried in
    the order of :func:`device_order`; the first on which an OpenGL 3.3 context opens draws
    (:attr:`device`), and why each one before it did not is kept in
    :attr:`devices_refused`. Raises :class:`GLRendererError` when none opens.
    """

    def __init__(self, shapes: Sequence[Shape], near: float, far: float,
                 light_direction: ArrayLike, devices: Sequence[EGLDevice] | None = None
                 ) -> None:
        """Create the context, compile the shaders, upload the triangles (module docstring)."""
        try:
            import moderngl  # here: importing the module loads no OpenGL
        except ImportError as exc:
            raise GLRendererError(f'moderngl is not installed: {exc}') from None
        parts = 1 + max((s.part for s in shapes), default=0)
        if parts > MAX_PARTS:
            raise GLRendererError(f'{parts} parts, at most {MAX_PARTS}')
        self.parts = parts
        self.near, self.far = float(near), float(far)
        light = np.asarray(light_direction, dtype=float)
        if light.shape != (3,) or not np.all(np.isfinite(light)) or not np.any(light):
            raise GLRendererError(f'light_direction must be 3 finite values, not all 0: '
                                  f'{light_direction!r}')
        self._light = tuple(light / np.linalg.norm(light))
        self._moderngl = moderngl
        self._ctx = None
        self._fbos = []
        self._rgba = []  # a readback buffer a pass (_readback)
        #: Why a context did not open on each device tried before the one that draws.
        self.devices_refused = []
        order = ([None] if os.environ.get(DEVICE_INDEX_VARIABLE)
                 else device_order(egl_devices() if devices is None else devices))
        for index in order:
            options = {} if index is None else {'device_index': index}
            try:
                self._ctx = moderngl.create_context(standalone=True, backend='egl',
                                                    require=330, **options)
                break
            except Exception as exc:  # glcontext raises plain Exceptions
                self.devices_refused.append(f'EGL device {index}: {exc}')
        if self._ctx is None:
            raise GLRendererError('no standalone EGL OpenGL 3.3 context: '
                                  + '; '.join(self.devices_refused))
        name = self._ctx.info.get('GL_RENDERER', '?')
        #: The OpenGL implementation that draws (e.g. 'llvmpipe (LLVM 15.0.6, 256 bits)').
        self.device = RenderDevice(name, is_hardware(name))
        try:
            with self._use():
                self._upload(shapes, parts)
        except Exception:
            self._ctx.release()  # with whatever _upload made in it
            self._ctx = None
            raise

    def __repr__(self) -> str:
        """Name the renderer and its device."""
        kind = 'GPU' if self.device.hardware else 'software'
        return f'opengl on {self.device.gl_renderer} ({kind})'

    def _upload(self, shapes, parts):
        """Compile the shaders and upload the triangles into one vertex buffer."""
        # Program 0 lights each pixel (smooth shapes), program 1 each vertex (flat shapes).
        fill = {'parts': parts, 'lighting': _LIGHTING}
        self._programs = [
            self._ctx.program(vertex_shader=_VERTEX_SHADER % fill,
                              fragment_shader=_FRAGMENT_SHADER % fill),
            self._ctx.program(vertex_shader=_FLAT_VERTEX_SHADER % fill,
                              fragment_shader=_FLAT_FRAGMENT_SHADER)]
        for program in self._programs:
            program['light'].value = self._light
        rows = np.concatenate([
            np.column_stack([shape.positions, shape.normals,
                             np.tile(np.asarray(shape.rgb, float), (len(shape.positions), 1)),
                             np.full(len(shape.positions), shape.part)])
            for shape in shapes])
        # Shared corners once, as indices: llvmpipe shades each vertex of the buffer once per
        # draw, and a triangle soup has six times as many (the marker spheres: 15360 against
        # 2562 each). The vertices in the order of their first use, so that a shape's are
        # together and a draw of some shapes only (render) shades theirs: llvmpipe shades
        # every vertex between the least and the greatest index a draw uses.
        unique, first, indices = np.unique(rows, axis=0, return_index=True,
                                           return_inverse=True)
        order = np.argsort(first)
        rank = np.empty_like(order)
        rank[order] = np.arange(len(order))
        unique, indices = unique[order], rank[np.reshape(indices, -1)]
        data = np.zeros(len(unique), dtype=[('position', 'f4', 3), ('normal', 'f4', 3),
                                            ('colour', 'f4', 3), ('part', 'i4')])
        data['position'], data['normal'] = unique[:, 0:3], unique[:, 3:6]
        data['colour'], data['part'] = unique[:, 6:9], unique[:, 9]
        self.triangles = len(rows) // 3
        self.vertices = len(unique)
        self._vbo = self._ctx.buffer(data.tobytes())
        self._ibo = self._ctx.buffer(np.asarray(indices, dtype='u4').tobytes())
        # Each shape's triangles are one run of the index buffer, in the order given; its
        # bounding sphere (centre in its part's frame, radius) decides whether a pass draws it.
        counts = np.array([len(shape.positions) for shape in shapes])
        self._shape_first = np.concatenate([[0], np.cumsum(counts)[:-1]])
        self._shape_count = counts
        self._shape_part = np.array([shape.part for shape in shapes])
        # A flat shape (each triangle's normals equal: boxes, the ground) is lit once a vertex,
        # with the normal each of its pixels would interpolate: the fragment shader was a
        # third of a full HD720 pass (measured: 7.7 -> 6.6 ms a pass, the same pixels).
        self._shape_program = np.array([
            int(np.all(np.reshape(shape.normals, (-1, 3, 3))
                       == np.reshape(shape.normals, (-1, 3, 3))[:, :1])) for shape in shapes])
        centres, radii = [], []
        for shape in shapes:
            points = np.asarray(shape.positions, dtype=float)
            centre = 0.5 * (points.min(axis=0) + points.max(axis=0))
            centres.append(centre)
            radii.append(np.linalg.norm(points - centre, axis=1).max())
        self._shape_centre = np.array(centres)
        self._shape_radius = np.array(radii)
        self._vaos = [self._ctx.vertex_array(
            program, [(self._vbo, '3f 3f 3f 1i', 'in_position', 'in_normal',
                       'in_colour', 'in_part')], index_buffer=self._ibo,
            index_element_size=4) for program in self._programs]

    @contextlib.contextmanager
    def _use(self):
        """Make our context current in the block, and what was current before after it."""
        with self._ctx:
            yield

    def _framebuffer(self, index, width, height):
        """Return framebuffer ``index`` (one per pass), at least ``width`` x ``height``."""
        while len(self._fbos) <= index:
            self._fbos.append(None)
        fbo = self._fbos[index]
        if fbo is None or width > fbo.width or height > fbo.height:
            size = (max(width, fbo.width if fbo else 0), max(height, fbo.height if fbo else 0))
            if fbo is not None:
                self._release(fbo)
            fbo = self._fbos[index] = self._ctx.framebuffer(
                color_attachments=[self._ctx.renderbuffer(size, components=4)],
                depth_attachment=self._ctx.depth_renderbuffer(size))
        return fbo

    @staticmethod
    def _release(fbo):
        """Release a framebuffer and its attachments (moderngl leaves those alive)."""
        for attachment in (*fbo.color_attachments, fbo.depth_attachment):
            attachment.release()
        fbo.release()

    def render(self, part_poses: ArrayLike, view: ArrayLike, projection: ArrayLike,
               width: int, height: int,
               covered: Sequence[tuple[int, int, int, int]] = ()) -> NDArray[np.uint8]:
        """
        Return the (height, width, 3) uint8 image of the scene.

        ``part_poses`` (P, 4, 4): the pose in {O} of each part; ``view``: the OpenGL view
        matrix (:func:`ibvs_sim.rendering.view_matrix`); ``projection``: the OpenGL
        projection matrix of the image (:func:`ibvs_sim.rendering.projection_matrix`).
        ``covered``: windows (u0, v0, u1, v1) of this image, u1 and v1 excluded, that the
        caller paints over (the markers' supersampled windows); a shape whose image lies
        inside one is not drawn there, so the pixels outside them are what they would be
        without, and inside them anything. Only the shapes that may reach the image (and are
        not covered) are drawn (:meth:`_runs`): the image is the same to the bit.
        """
        return self.render_passes(part_poses, [(view, projection, width, height, covered)])[0]

    def render_passes(self, part_poses: ArrayLike, passes: Sequence[Pass]
                      ) -> list[NDArray[np.uint8]]:
        """
        Return the images of several passes over one state of the scene, as :meth:`render`.

        ``passes``: (view, projection, width, height, covered) each, the arguments of
        :meth:`render`. Each pass has a framebuffer of its own; all are drawn before any is
        read, so that llvmpipe's threads rasterise one while this thread prepares the next,
        and our context is made current once (measured: 1-1.5 ms less a stereo pair with its
        marker windows, at HD720 and VGA, than one pass after the other).
        """
        poses = np.asarray(part_poses, dtype=float)
        if poses.shape != (self.parts, 4, 4):
            raise GLRendererError(f'part_poses must be ({self.parts}, 4, 4), got {poses.shape}')
        flip = np.diag([1.0, -1.0, 1.0, 1.0])  # window row j = image row j (module docstring)
        # GLSL matrices are column-major: the transposes, row by row.
        rotation = np.ascontiguousarray(poses[:, :3, :3].transpose(0, 2, 1), dtype='f4')
        drawn = []
        with self._use():
            for program in self._programs:
                program['rotation'].write(rotation)
            self._ctx.front_face = 'cw'  # counter-clockwise in {O}, y flipped (docstring)
            self._ctx.enable_only(self._moderngl.DEPTH_TEST | self._moderngl.CULL_FACE)
            for index, (view, projection, width, height, covered) in enumerate(passes):
                width, height = int(width), int(height)
                clip = flip @ np.asarray(projection, dtype=float)
                view = np.asarray(view, dtype=float)
                mvp = clip @ view @ poses
                modelview = view @ poses
                mvp = np.ascontiguousarray(mvp.transpose(0, 2, 1), dtype='f4')
                for program in self._programs:
                    program['mvp'].write(mvp)
                fbo = self._framebuffer(index, width, height)
                fbo.use()
                viewport = (0, 0, width, height)
                fbo.viewport = viewport
                fbo.clear(*BACKGROUND_RGB, 1.0, depth=1.0, viewport=viewport)
                for first, count, program in self._runs(modelview, clip, width, height,
                                                        covered):
                    self._vaos[program].render(self._moderngl.TRIANGLES, vertices=count,
                                               first=first)
                drawn.append((fbo, viewport))
            images = []
            for index, (fbo, viewport) in enumerate(drawn):
                # Read as the framebuffer holds it (RGBA) and drop alpha in OpenCV: Mesa
                # packs RGB pixel by pixel, 0.9 ms an HD720 image on llvmpipe against
                # 0.08 + 0.08 ms; the same bytes.
                rgba = self._readback(index, viewport[2], viewport[3])
                fbo.read_into(rgba, viewport=viewport, components=4, alignment=1)
                images.append(cv2.cvtColor(rgba, cv2.COLOR_RGBA2RGB))
        return images

    def _readback(self, index, width, height):
        """Return pass ``index``'s (height, width, 4) RGBA buffer, kept between calls."""
        while len(self._rgba) <= index:
            self._rgba.append(np.empty((0, 0, 4), np.uint8))
        if self._rgba[index].shape[:2] != (height, width):
            self._rgba[index] = np.empty((height, width, 4), np.uint8)
        return self._rgba[index]

    def _runs(self, modelview, clip, width, height, covered):
        """
        Return the (first index, index count, program) runs of the shapes a pass draws.

        ``modelview`` (P, 4, 4): each part's pose in the eye frame; ``clip``: eye to clip
        coordinates. A shape is left out where the cube around its bounding sphere, axis-
        aligned in the eye frame (that of :func:`ibvs_sim.rendering.focus_windows`), cannot
        give a pixel: all eight corners lie beyond one plane of the clip volume (all its
        points do, it is convex), or its image lies inside a window of ``covered``: when the
        cube lies in front of the eye, its image is inside the convex hull of its corners'
        images, whose bounding box, grown by a pixel, is tested. Pixel (i, j) is sampled at
        window coordinates (i + 1/2, j + 1/2). A shape left out would draw no fragment
        there, so the image is the same; the order of those drawn is kept (the depth test's
        ties). Consecutive shapes drawn by one program make one run.
        """
        signs = np.array([[sx, sy, sz, 0.0] for sx in (-1, 1) for sy in (-1, 1)
                          for sz in (-1, 1)])
        m = modelview[self._shape_part]  # (n, 4, 4)
        eye = m[:, :, :3] @ self._shape_centre[:, :, None] + m[:, :, 3:]  # (n, 4, 1)
        corners = (eye[:, None, :, 0] + self._shape_radius[:, None, None] * signs) @ clip.T
        xyz, w = corners[:, :, :3], corners[:, :, 3:]
        margin = 1e-3 * np.abs(w)  # far more than float32's rounding
        outside = (np.all(xyz - w > margin, axis=1) | np.all(xyz + w < -margin, axis=1))
        draw = ~np.any(outside, axis=1)
        if len(covered):
            ahead = np.all(w[:, :, 0] > 0.0, axis=1)
            ndc = xyz[:, :, :2] / np.where(w > 0.0, w, 1.0)
            window = (ndc + 1.0) * (0.5 * np.array([width, height]))
            low = np.floor(window.min(axis=1)) - 1.0  # (n, 2): lowest i, j that may be hit
            high = np.ceil(window.max(axis=1)) + 1.0
            for u0, v0, u1, v1 in covered:
                inside = ((low[:, 0] >= u0) & (low[:, 1] >= v0)
                          & (high[:, 0] < u1) & (high[:, 1] < v1))
                draw &= ~(ahead & inside)
        runs = []
        for first, count, program, on in zip(self._shape_first, self._shape_count,
                                             self._shape_program, draw):
            if not on:
                continue
            if runs and runs[-1][0] + runs[-1][1] == first and runs[-1][2] == program:
                runs[-1][1] += int(count)
            else:
                runs.append([int(first), int(count), int(program)])
        return runs

    def close(self) -> None:
        """Release the context (idempotent)."""
        if self._ctx is not None:
            with self._use():
                for vao, program in zip(self._vaos, self._programs):
                    vao.release()
                    program.release()
                self._vbo.release()
                self._ibo.release()
                for fbo in self._fbos:
                    if fbo is not None:
                        self._release(fbo)
            self._ctx.release()
            self._ctx = None
