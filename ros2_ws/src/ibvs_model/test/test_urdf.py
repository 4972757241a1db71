"""
Tests of the URDF generator: structure, DH frames (eq. 4-7) and mass estimates.

The URDF is read back with xml.etree only; the frames it describes are composed here from
its own <origin> elements and compared with ibvs_model's forward kinematics. (PyBullet's
reading of the same file is tested in ibvs_sim.)
"""

import math
import xml.etree.ElementTree as ET

from ibvs_model import IRB4600, joint_frames
from ibvs_model.mass_model import joint_efforts, ROBOT_MASS_KG
from ibvs_model.mesh import icosphere_obj, MARKER_MESH
from ibvs_model.scene import MARKER_RADIUS_M, MARKER_RGB
from ibvs_model.urdf import JOINT_NAMES, robot_urdf, write_urdf
import numpy as np
import pytest

SCALED = IRB4600.scaled(1.1, 0.9)


def _floats(text):
    return np.array([float(v) for v in text.split()])


def _rpy(rpy):
    r, p, y = rpy
    rx = np.array([[1, 0, 0], [0, math.cos(r), -math.sin(r)], [0, math.sin(r), math.cos(r)]])
    ry = np.array([[math.cos(p), 0, math.sin(p)], [0, 1, 0], [-math.sin(p), 0, math.cos(p)]])
    rz = np.array([[math.cos(y), -math.sin(y), 0], [math.sin(y), math.cos(y), 0], [0, 0, 1]])
    return rz @ ry @ rx


def _origin(element):
    origin = element.find('origin')
    tf = np.eye(4)
    if origin is not None:
        tf[:3, :3] = _rpy(_floats(origin.get('rpy', '0 0 0')))
        tf[:3, 3] = _floats(origin.get('xyz', '0 0 0'))
    return tf


def _rot_z(angle):
    tf = np.eye(4)
    tf[:2, :2] = [[math.cos(angle), -math.sin(angle)], [math.sin(angle), math.cos(angle)]]
    return tf


def _link_frames(root, q):
    """Compose every link's frame in base_link from the URDF's joints (URDF semantics)."""
    joints = {j.find('child').get('link'): j for j in root.findall('joint')}
    q_of = dict(zip(JOINT_NAMES, q))
    frames = {'base_link': np.eye(4)}

    def frame(link):
        if link not in frames:
            joint = joints[link]
            tf = frame(joint.find('parent').get('link')) @ _origin(joint)
            if joint.get('type') == 'revolute':
                axis = _floats(joint.find('axis').get('xyz'))
                assert np.allclose(axis, [0.0, 0.0, 1.0])
                tf = tf @ _rot_z(q_of[joint.get('name')])
            frames[link] = tf
        return frames[link]

    for link in root.findall('link'):
        frame(link.get('name'))
    return frames


@pytest.fixture(scope='module', params=[IRB4600, SCALED], ids=['paper', 'scaled'])
def robot(request):
    return request.param, ET.fromstring(robot_urdf(request.param))


def test_structure_names_and_limits(robot):
    params, root = robot
    links = [link.get('name') for link in root.findall('link')]
    assert links[:7] == ['base_link'] + [f'link_{i}' for i in range(1, 7)]
    assert {'tool0', 'screwdriver', 'marker_1', 'marker_2'} <= set(links)
    revolute = [j for j in root.findall('joint') if j.get('type') == 'revolute']
    assert [j.get('name') for j in revolute] == list(JOINT_NAMES)
    for i, joint in enumerate(revolute):
        limit = joint.find('limit')
        assert float(limit.get('lower')) == params.q_min[i]
        assert float(limit.get('upper')) == params.q_max[i]
        assert float(limit.get('velocity')) == params.qd_max[i]
        assert float(limit.get('effort')) > 0.0
        dyn = joint.find('dynamics')
        assert float(dyn.get('damping')) == 0.0 and float(dyn.get('friction')) == 0.0
    others = [j for j in root.findall('joint') if j.get('type') != 'revolute']
    assert all(j.get('type') == 'fixed' for j in others)
    # No collision shapes: the arm moves in free space (module docstring of ibvs_model.urdf).
    assert root.find('.//collision') is None


def test_link_frames_are_the_dh_frames(robot):
    """link_i = T_{i-1}^0 Rot_z(q_i + offset_i), tool0 = T_6^0 = T_E^O (eq. 7), markers P1, P2."""
    params, root = robot
    offsets = params.dh_table()[:, 3]
    rng = np.random.default_rng(4)
    for _ in range(50):
        q = rng.uniform(params.q_min, params.q_max)
        frames = _link_frames(root, q)
        dh = joint_frames(q, params)
        for i in range(1, 7):
            expected = dh[i - 1] @ _rot_z(q[i - 1] + offsets[i - 1])
            assert np.allclose(frames[f'link_{i}'], expected, atol=1e-12)
        assert np.allclose(frames['tool0'], dh[6], atol=1e-12)
        for k, p_e in enumerate(params.fiducials_E, start=1):
            assert np.allclose(frames[f'marker_{k}'][:3, 3], dh[6][:3, :3] @ p_e + dh[6][:3, 3],
                               atol=1e-12)


def _inertial(link):
    inertial = link.find('inertial')
    if inertial is None:
        return None
    values = inertial.find('inertia').attrib
    tensor = np.array([[values['ixx'], values['ixy'], values['ixz']],
                       [values['ixy'], values['iyy'], values['iyz']],
                       [values['ixz'], values['iyz'], values['izz']]], dtype=float)
    rot = _origin(inertial)[:3, :3]
    return float(inertial.find('mass').get('value')), rot @ tensor @ rot.T


def test_inertials_total_mass_and_physical(robot):
    params, root = robot
    links = {link.get('name'): link for link in root.findall('link')}
    robot_mass = 0.0
    for name, link in links.items():
        props = _inertial(link)
        assert props is not None, f'{name} has no inertial (PyBullet would give it 1 kg)'
        mass, tensor = props
        if name == 'tool0':
            assert mass == 0.0
            continue
        assert mass > 0.0
        moments = np.linalg.eigvalsh(tensor)
        assert np.all(moments > 0.0)
        # Triangle inequality of principal moments: a realisable mass distribution.
        assert moments[0] + moments[1] >= moments[2] * (1.0 - 1e-9)
        if name.startswith(('base_link', 'link_')):
            robot_mass += mass
    assert robot_mass == pytest.approx(ROBOT_MASS_KG, rel=1e-12)
    # The tool is light next to the arm: a 4 mm steel shaft and two ABS spheres.
    tool_mass = sum(_inertial(links[n])[0] for n in ('screwdriver', 'marker_1', 'marker_2'))
    assert 0.05 < tool_mass < 0.5


def test_markers_spheres_in_their_colours(robot):
    _, root = robot
    colours = {m.get('name'): _floats(m.find('color').get('rgba'))
               for m in root.findall('material')}
    links = {link.get('name'): link for link in root.findall('link')}
    for k, rgb in enumerate(MARKER_RGB, start=1):
        visual = links[f'marker_{k}'].find('visual')
        mesh = visual.find('geometry/mesh')
        assert mesh.get('filename') == MARKER_MESH
        assert np.all(_floats(mesh.get('scale')) == MARKER_RADIUS_M)
        assert np.allclose(_origin(visual)[:3, 3], 0.0)
        rgba = colours[visual.find('material').get('name')]
        assert np.allclose(rgba[:3] * 255.0, rgb)
    # Everything else is grey: no channel differs from another by more than 5 %.
    for name, link in links.items():
        if name.startswith('marker_'):
            continue
        for visual in link.findall('visual'):
            rgba = colours[visual.find('material').get('name')]
            assert np.ptp(rgba[:3]) <= 0.05, f'{name} is not grey: {rgba}'


def test_nothing_near_p1_but_the_quill_and_shaft(robot):
    """No visual of link 6 or the tool other than thin rods comes within 5 cm of P1's surface."""
    params, root = robot
    links = {link.get('name'): link for link in root.findall('link')}
    lt = params.Lt
    for visual in links['link_6'].findall('visual'):
        cyl = visual.find('geometry/cylinder')
        centre = _origin(visual)[:3, 3]
        top = centre[2] + float(cyl.get('length')) / 2.0
        if float(cyl.get('radius')) > 0.01:
            # A wide part must end at least 5 cm before P1's sphere (at Lt - radius).
            assert top <= lt - MARKER_RADIUS_M - 0.05
    shaft = links['screwdriver'].find('visual/geometry/cylinder')
    assert float(shaft.get('radius')) < MARKER_RADIUS_M / 5.0
    assert float(shaft.get('length')) == params.L_tool


def test_without_tool_keeps_tool0():
    root = ET.fromstring(robot_urdf(IRB4600, with_tool=False))
    names = {link.get('name') for link in root.findall('link')}
    assert 'tool0' in names
    assert not names & {'screwdriver', 'marker_1', 'marker_2'}
    q = np.radians([10.0, 20.0, -30.0, 40.0, 50.0, 60.0])
    assert np.allclose(_link_frames(root, q)['tool0'], joint_frames(q)[6], atol=1e-12)


def test_efforts_follow_the_load():
    """Proximal joints carry more than distal ones; a longer arm needs more torque."""
    paper = joint_efforts(IRB4600)
    assert paper[1] > paper[2] > paper[3] > paper[4]
    longer = joint_efforts(IRB4600.scaled(1.2, 1.2))
    assert longer[1] > paper[1] and longer[2] > paper[2]


def test_write_urdf_round_trip(tmp_path):
    path = write_urdf(tmp_path / 'robot.urdf', SCALED)
    assert path.read_text() == robot_urdf(SCALED)
    assert (tmp_path / MARKER_MESH).read_text() == icosphere_obj()
    assert robot_urdf(SCALED) != robot_urdf(IRB4600)


def _read_obj(text):
    vertices = np.array([[float(v) for v in line.split()[1:]]
                         for line in text.splitlines() if line.startswith('v ')])
    normals = np.array([[float(v) for v in line.split()[1:]]
                        for line in text.splitlines() if line.startswith('vn ')])
    faces = np.array([[int(c.split('//')[0]) - 1 for c in line.split()[1:]]
                      for line in text.splitlines() if line.startswith('f ')])
    return vertices, normals, faces


@pytest.mark.parametrize('subdivisions', [0, 2, 4])
def test_icosphere_is_a_closed_outward_sphere(subdivisions):
    vertices, normals, faces = _read_obj(icosphere_obj(subdivisions))
    n_faces = 20 * 4 ** subdivisions
    assert faces.shape == (n_faces, 3)
    # Euler: V - E + F = 2 for a closed genus-0 surface, every edge shared by two faces.
    edges = {}
    for face in faces:
        for a, b in zip(face, np.roll(face, -1)):
            edges[(min(a, b), max(a, b))] = edges.get((min(a, b), max(a, b)), 0) + 1
    assert set(edges.values()) == {2}
    assert len(vertices) - len(edges) + n_faces == 2
    assert np.allclose(np.linalg.norm(vertices, axis=1), 1.0, atol=2e-6)
    assert np.array_equal(normals, vertices)
    # Counter-clockwise seen from outside: every face normal points away from the centre.
    a, b, c = (vertices[faces[:, i]] for i in range(3))
    assert np.all(np.einsum('ij,ij->i', np.cross(b - a, c - a), a + b + c) > 0.0)
    # The faces' planes lie within 1 - cos(half the largest edge's arc) of the sphere.
    if subdivisions == 4:
        centroid_radius = np.linalg.norm((a + b + c) / 3.0, axis=1)
        assert centroid_radius.min() > 0.9985
