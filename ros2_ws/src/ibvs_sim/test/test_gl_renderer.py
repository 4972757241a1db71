"""
The OpenGL renderer (ibvs_sim.gl_renderer): camera model, shapes, scene, choice of device.

No ROS. The camera model is checked on the marker sphere alone (the mesh the URDF refers to,
ibvs_model.mesh), rendered with 8 x 8 samples per pixel around it: the centroid of its
samples is the centre of the sphere's image as ibvs_model's camera projects it
(ibvs_sim.markers.sphere_image_centre, eq. 16-22 applied to the sphere's tangent cone).
Every test that draws needs a standalone EGL context; where none can be created it is skipped
with the reason (it can on the project's machines, with Mesa's llvmpipe). None needs a GPU:
the choice of device is tested on the fallback path (a GPU that is listed but refuses).
"""

from contextlib import contextmanager

from ibvs_model import inverse_kinematics, look_at, paper, StereoCamera, StereoIntrinsics
from ibvs_model.mesh import icosphere_obj
from ibvs_model.scene import MARKER_RADIUS_M, MARKER_RGB
from ibvs_sim import markers
from ibvs_sim.gl_renderer import (box_triangles, cylinder_triangles, device_order,
                                  egl_devices, EGLDevice, GLRenderer, GLRendererError,
                                  is_hardware, obj_triangles, Shape, SOFTWARE_DEVICE)
from ibvs_sim.rendering import (FAR_M, focus_windows, lens_poses, NEAR_M, projection_matrix,
                                supersampled, view_matrix, window_intrinsics)
from ibvs_sim.rendering import Renderer
from ibvs_sim.world import DEFAULT_FOCUS_SUPERSAMPLING, LIGHT_DIRECTION, World
import numpy as np
import pytest

SAMPLES = 8


@pytest.fixture(scope='module')
def sphere_renderer():
    """Return a GLRenderer of marker 1's sphere alone (part 0); skip without OpenGL."""
    positions, normals = obj_triangles(icosphere_obj(), [MARKER_RADIUS_M] * 3)
    rgb = tuple(c / 255.0 for c in MARKER_RGB[0])
    try:
        renderer = GLRenderer([Shape(0, positions, normals, rgb)], NEAR_M, FAR_M,
                              LIGHT_DIRECTION)
    except GLRendererError as exc:
        pytest.skip(f'no OpenGL context here: {exc}')
    yield renderer
    renderer.close()


def _sphere_centre(renderer, camera, centre_O):
    """Return the measured (u_l, u_r, v) of the sphere at ``centre_O``: sample centroids."""
    k = camera.intrinsics
    pose = np.eye(4)
    pose[:3, 3] = centre_O
    measured = []
    for lens in lens_poses(camera):
        (window,) = focus_windows(k, lens, [(centre_O, MARKER_RADIUS_M)])
        fine = supersampled(window_intrinsics(k, window), SAMPLES)
        image = renderer.render(pose[None], view_matrix(lens), projection_matrix(fine),
                                fine.width, fine.height)
        u, v, _ = markers.mask_centre(markers.colour_masks(image)[0])
        # Sample (i, j) of the fine image is at pixel ((i + 1/2) / s - 1/2) of the window.
        measured.append(((u + 0.5) / SAMPLES - 0.5 + window[0],
                         (v + 0.5) / SAMPLES - 0.5 + window[1]))
    (ul, vl), (ur, vr) = measured
    return np.array([ul, ur, 0.5 * (vl + vr)])


@pytest.mark.parametrize('resolution', ['HD720', 'VGA'])
def test_a_marker_is_drawn_where_the_camera_model_projects_it(sphere_renderer, resolution):
    """20 sphere positions across the view, 1.5-3 m deep: within 0.05 px (measured 0.006)."""
    camera = StereoCamera(StereoIntrinsics.zed2(resolution),
                          look_at(paper.CAMERA_EYE, paper.CAMERA_LOOK_AT))
    rng = np.random.default_rng(11)
    errors = []
    for _ in range(20):
        z = rng.uniform(1.5, 3.0)
        inside = np.array([rng.uniform(-0.35, 0.35) * z, rng.uniform(-0.2, 0.2) * z, z])
        centre = camera.to_base(inside[None])[0]
        exact, _ = markers.sphere_image_centre(camera, centre, MARKER_RADIUS_M)
        errors.append(_sphere_centre(sphere_renderer, camera, centre) - exact)
    errors = np.abs(errors)
    assert errors.max() <= 0.05, errors.max()
    # Not by luck: half a pixel off in the principal point, or an unflipped v, fails.
    assert np.median(errors) <= 0.01, np.median(errors)


def test_the_image_rows_run_down_and_columns_right(sphere_renderer):
    """A sphere right of and below the optical axis shows right of and below the centre."""
    camera = StereoCamera(StereoIntrinsics.zed2('VGA'),
                          look_at(paper.CAMERA_EYE, paper.CAMERA_LOOK_AT))
    centre = camera.to_base(np.array([[0.4, 0.2, 2.0]]))[0]
    ul, ur, v = _sphere_centre(sphere_renderer, camera, centre)
    k = camera.intrinsics
    assert ul > ur > k.cu and v > k.cv


def test_part_poses_must_match_the_scene(sphere_renderer):
    k = StereoIntrinsics.zed2('VGA')
    with pytest.raises(GLRendererError, match='part_poses'):
        sphere_renderer.render(np.tile(np.eye(4), (2, 1, 1)), np.eye(4),
                               projection_matrix(k), k.width, k.height)


def _two_spheres(offset_m):
    """Return Shapes of two marker spheres of one part: at the origin and at ``offset_m``."""
    positions, normals = obj_triangles(icosphere_obj(), [MARKER_RADIUS_M] * 3)
    return [Shape(0, positions, normals, (1.0, 0.0, 0.0)),
            Shape(0, positions + np.asarray(offset_m), normals, (0.0, 0.0, 1.0))]


def _sphere_view(camera, renderer, k, covered=()):
    """Render ``renderer``'s part 0 at the origin seen by ``camera``'s left lens."""
    (lens, _) = lens_poses(camera)
    return renderer.render(np.eye(4)[None], view_matrix(lens), projection_matrix(k), k.width,
                           k.height, covered)


def _renderer(shapes):
    try:
        return GLRenderer(shapes, NEAR_M, FAR_M, LIGHT_DIRECTION)
    except GLRendererError as exc:
        pytest.skip(f'no OpenGL context here: {exc}')


@pytest.mark.parametrize('offset_m', [(5.0, 0.0, 0.0), (0.0, 0.0, 3.0), (0.0, 0.2, 0.0)])
def test_shapes_out_of_view_are_left_out_and_the_image_is_the_same(offset_m):
    """
    The second sphere beside the view, behind the camera, or in view: same image as drawn.

    An out-of-view shape is not drawn (its run is left out of the pass), and the image
    equals, to the bit, that of a scene without it (in view: with it).
    """
    camera = StereoCamera(StereoIntrinsics.zed2('VGA'), look_at((0.0, 0.0, 2.0), (0.0, 0.0, 0.0),
                                                                up=(0.0, 1.0, 0.0)))
    k = camera.intrinsics
    both = _renderer(_two_spheres(offset_m))
    alone = _renderer(_two_spheres(offset_m)[:1])
    try:
        (lens, _) = lens_poses(camera)
        flip = np.diag([1.0, -1.0, 1.0, 1.0])
        runs = both._runs(view_matrix(lens)[None], flip @ projection_matrix(k), k.width,
                          k.height, ())
        in_view = offset_m == (0.0, 0.2, 0.0)
        sphere = both._shape_count[0]  # indices of one sphere
        assert sum(count for _, count, _ in runs) == (2 * sphere if in_view else sphere)
        image = _sphere_view(camera, both, k).astype(int)
        if in_view:
            assert np.any(image[:, :, 2] - image[:, :, 0] > 50)  # the blue sphere
            assert not np.array_equal(image, _sphere_view(camera, alone, k))
        else:
            assert np.array_equal(image, _sphere_view(camera, alone, k))
    finally:
        both.close()
        alone.close()


def test_a_shape_inside_a_covered_window_is_left_out_and_nothing_else_changes():
    """The sphere inside its focus window is not drawn; every pixel outside it is the same."""
    camera = StereoCamera(StereoIntrinsics.zed2('HD720'),
                          look_at((0.0, 0.0, 2.0), (0.0, 0.0, 0.0), up=(0.0, 1.0, 0.0)))
    k = camera.intrinsics
    renderer = _renderer(_two_spheres((0.3, 0.0, 0.0)))
    try:
        (lens, _) = lens_poses(camera)
        (window,) = focus_windows(k, lens, [(np.zeros(3), MARKER_RADIUS_M)])
        full = _sphere_view(camera, renderer, k)
        covered = _sphere_view(camera, renderer, k, [window])
        u0, v0, u1, v1 = window
        inside = np.zeros(full.shape[:2], dtype=bool)
        inside[v0:v1, u0:u1] = True
        assert np.array_equal(full[~inside], covered[~inside])
        red = full[:, :, 0].astype(int) - full[:, :, 1] > 50
        assert red[inside].sum() > 100 and not red[~inside].any()
        # Left out, not merely painted: the window shows the background there.
        assert np.all(covered[inside] == covered[0, 0])
        # A window that holds only part of the sphere's image leaves it drawn.
        half = (u0, v0, (u0 + u1) // 2, v1)
        assert np.array_equal(_sphere_view(camera, renderer, k, [half]), full)
    finally:
        renderer.close()


def test_passes_drawn_together_equal_passes_drawn_one_by_one(sphere_renderer):
    """render_passes: each image as render gives it, whatever the order and sizes of the passes."""
    camera = StereoCamera(StereoIntrinsics.zed2('HD720'),
                          look_at((0.0, 0.0, 2.0), (0.0, 0.0, 0.0), up=(0.0, 1.0, 0.0)))
    k = camera.intrinsics
    pose = np.eye(4)[None]
    passes = []
    for lens in lens_poses(camera):
        (window,) = focus_windows(k, lens, [(np.zeros(3), MARKER_RADIUS_M)])
        fine = supersampled(window_intrinsics(k, window), SAMPLES)
        passes += [(view_matrix(lens), projection_matrix(k), k.width, k.height, [window]),
                   (view_matrix(lens), projection_matrix(fine), fine.width, fine.height, ())]
    alone = [sphere_renderer.render(pose, *p) for p in passes]
    for order in (passes, passes[::-1]):
        together = sphere_renderer.render_passes(pose, order)
        expected = alone if order is passes else alone[::-1]
        assert all(np.array_equal(a, b) for a, b in zip(together, expected))
    # Not trivially equal: the windows hold the sphere, which the full images leave out.
    assert np.any(alone[1] != alone[1][0, 0]) and np.any(alone[3] != alone[3][0, 0])
    assert np.all(alone[0] == alone[0][0, 0])


@contextmanager
def _world_at_target(resolution):
    """Yield (World with the arm at the paper's target, the paper's camera)."""
    camera = StereoCamera(StereoIntrinsics.zed2(resolution),
                          look_at(paper.CAMERA_EYE, paper.CAMERA_LOOK_AT))
    try:
        world = World()
    except Exception as exc:
        pytest.skip(f'no OpenGL context here: {exc}')
    try:
        world.reset(inverse_kinematics(paper.target_pose()))
        yield world, camera
    finally:
        world.close()


def test_a_lens_alone_is_drawn_as_in_the_stereo_pair():
    """render_lens gives the image that render_stereo gives that lens."""
    with _world_at_target('VGA') as (world, camera):
        focus = world.marker_spheres()
        pair = world.render_stereo(camera, 1, focus, DEFAULT_FOCUS_SUPERSAMPLING)
        for lens, image in zip(lens_poses(camera), pair):
            assert np.array_equal(world.render_lens(lens, camera.intrinsics, 1, focus,
                                                    DEFAULT_FOCUS_SUPERSAMPLING), image)


def test_flat_shapes_lit_once_a_vertex_look_as_lit_once_a_pixel():
    """
    The scene at the target pose, HD720: boxes and ground by the flat program, as by the other.

    Lit once a vertex with the normal that each pixel would interpolate; float rounding may
    in principle move a pixel by one grey level (measured: none of 2 x 921600 moves).
    """
    with _world_at_target('HD720') as (world, camera):
        renderer = world.renderer
        programs = renderer._shape_program.copy()
        assert programs.sum() >= 4 and (1 - programs).sum() >= 4  # boxes, ground; the rest
        pair = world.render_stereo(camera)
        renderer._shape_program[:] = 0
        per_pixel = world.render_stereo(camera)
        renderer._shape_program[:] = programs
    for a, b in zip(pair, per_pixel):
        moved = np.any(a != b, axis=2)
        assert np.abs(a.astype(int) - b).max() <= 1 and moved.mean() <= 1e-4, moved.sum()


def _volume(positions):
    """Signed volume enclosed by triangles (divergence theorem): > 0 when wound outwards."""
    a, b, c = positions[0::3], positions[1::3], positions[2::3]
    return float(np.sum(np.einsum('ij,ij->i', a, np.cross(b, c))) / 6.0)


@pytest.mark.parametrize('shape, volume', [
    (box_triangles((0.1, 0.2, 0.3)), 8 * 0.1 * 0.2 * 0.3),
    (cylinder_triangles(0.2, 0.5, segments=64), 0.5 * 0.5 * 64 * 0.2 ** 2 * np.sin(np.pi / 32)),
    (obj_triangles(icosphere_obj(), (0.3, 0.3, 0.3)), 4.0 / 3.0 * np.pi * 0.3 ** 3),
])
def test_shapes_are_closed_wound_outwards_with_outward_normals(shape, volume):
    positions, normals = shape
    # A closed surface wound counter-clockwise from outside encloses its volume (the
    # icosphere, inscribed in the sphere, holds 0.2 % less).
    assert _volume(positions) == pytest.approx(volume, rel=3e-3)
    assert _volume(positions + 5.0) == pytest.approx(volume, rel=3e-3)
    face = np.cross(positions[1::3] - positions[0::3], positions[2::3] - positions[0::3])
    vertex = normals.reshape(-1, 3, 3).sum(axis=1)
    assert np.all(np.einsum('ij,ij->i', face, vertex) > 0.0)
    assert np.allclose(np.linalg.norm(normals, axis=1), 1.0)


def test_obj_faces_without_normals_get_flat_ones_and_polygons_are_refused():
    positions, normals = obj_triangles('v 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 3\n', (2.0, 1.0, 1.0))
    assert np.allclose(positions, [[0, 0, 0], [2, 0, 0], [0, 1, 0]])
    assert np.allclose(normals, [[0, 0, 1]] * 3)
    with pytest.raises(GLRendererError, match='triangles'):
        obj_triangles('v 0 0 0\nv 1 0 0\nv 1 1 0\nv 0 1 0\nf 1 2 3 4\n')


def _device(index, *extensions):
    return EGLDevice(index, frozenset(extensions))


def test_gpus_are_tried_first_in_egl_order_then_software():
    """The selection alone (no EGL): hardware devices by index, then Mesa's software one."""
    soft, gpu_a, gpu_b = (_device(0, SOFTWARE_DEVICE, 'EGL_EXT_device_drm_render_node'),
                          _device(1, 'EGL_EXT_device_drm', 'EGL_NV_device_cuda'),
                          _device(2, 'EGL_EXT_device_drm'))
    assert soft.software and not gpu_a.software
    assert device_order([soft, gpu_b, gpu_a]) == [1, 2, 0]
    assert device_order([soft]) == [0]
    assert device_order([]) == [None]  # EGL's default display where none is listed
    assert not is_hardware('llvmpipe (LLVM 15.0.6, 256 bits)')
    assert not is_hardware('softpipe')
    assert is_hardware('NVIDIA H100 80GB HBM3/PCIe/SSE2')


def test_a_gpu_that_refuses_falls_back_to_the_next_device(sphere_renderer):
    """
    A listed GPU on which no context opens is passed over, and why is kept.

    The fallback path on any machine: a device index past EGL's list stands for a GPU whose
    context fails; the renderer then opens where it would have without it, and draws.
    """
    real = egl_devices()
    missing = _device(len(real) + 7, 'EGL_EXT_device_drm')
    shapes = [Shape(0, *box_triangles((0.1, 0.1, 0.1)), (1.0, 0.0, 0.0))]
    renderer = GLRenderer(shapes, NEAR_M, FAR_M, LIGHT_DIRECTION, devices=[missing, *real])
    try:
        assert isinstance(renderer, GLRenderer) and isinstance(renderer.device.hardware, bool)
        assert renderer.device == sphere_renderer.device  # what this machine chose anyway
        assert len(renderer.devices_refused) == 1
        assert f'EGL device {missing.index}' in renderer.devices_refused[0]
        assert f'{renderer.device.gl_renderer}' in repr(renderer)
    finally:
        renderer.close()
    with pytest.raises(GLRendererError, match=f'EGL device {missing.index}'):
        GLRenderer(shapes, NEAR_M, FAR_M, LIGHT_DIRECTION, devices=[missing])


def test_the_world_holds_one_renderer_and_says_what_draws():
    """World's renderer is a Renderer; its device is the run's render_device."""
    with _world_at_target('VGA') as (world, _):
        assert isinstance(world.renderer, GLRenderer)
        for name in ('render_passes', 'close', 'device'):
            assert hasattr(Renderer, name) or name in Renderer.__annotations__
        assert world.render_device == world.renderer.device
        assert world.render_device.hardware == is_hardware(world.render_device.gl_renderer)
    physics = World(render=False)
    try:
        assert physics.renderer is None and physics.render_device is None
        with pytest.raises(RuntimeError, match='render false'):
            physics.render_stereo(StereoCamera(StereoIntrinsics.zed2('VGA'),
                                               look_at(paper.CAMERA_EYE, paper.CAMERA_LOOK_AT)))
    finally:
        physics.close()
