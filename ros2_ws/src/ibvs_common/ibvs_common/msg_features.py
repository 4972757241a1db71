"""
The feature node's messages: /ibvs/features (PolygonStamped) and /ibvs/feature_status.

p_I (6,) as one Point32 per marker (:func:`features_msg`, :func:`read_features`), measured
features checked against the image (:func:`check_features_in_image`) and
:class:`FeatureStatus` as a DiagnosticArray. Readers raise :class:`.input_error.InputError`.
"""

import math
from typing import NamedTuple, Union

from builtin_interfaces.msg import Time
from diagnostic_msgs.msg import DiagnosticArray, DiagnosticStatus, KeyValue
from geometry_msgs.msg import Point32, PolygonStamped
from ibvs_model import StereoIntrinsics
import numpy as np
from numpy.typing import ArrayLike, NDArray

from . import contract
from .input_error import InputError
from .msg_time import ns_stamp


def features_msg(features: ArrayLike, stamp: int | Time,
                 frame_id: str = contract.CAMERA_FRAME) -> PolygonStamped:
    """
    Return p_I (6,) as PolygonStamped: one point per marker, x = u_l, y = u_r, z = v.

    The values are rounded to float32 here, as Point32 carries them: the message holds what
    DDS delivers, also to a reader that gets the object itself (:mod:`.intra_process`).
    """
    p = np.asarray(features, dtype=float).reshape(2, 3).astype(np.float32)
    msg = PolygonStamped()
    msg.header.stamp = stamp if isinstance(stamp, Time) else ns_stamp(stamp)
    msg.header.frame_id = frame_id
    msg.polygon.points = [Point32(x=float(r[0]), y=float(r[1]), z=float(r[2])) for r in p]
    return msg


def read_features(msg: PolygonStamped) -> NDArray[np.float64]:
    """
    Return p_I (6,) from a PolygonStamped; :class:`InputError` if not 2 finite points.

    Point32 holds float32: features travel with about 1e-4 px resolution at HD720.
    """
    points = msg.polygon.points
    if len(points) != 2:
        raise InputError('wrong feature count', f'{len(points)} points, expected 2')
    values = np.array([[p.x, p.y, p.z] for p in points], dtype=float).reshape(6)
    if not np.all(np.isfinite(values)):
        raise InputError('non-finite features', f'{values.tolist()}')
    return values


#: How far (px) a measured feature may lie outside its image: the detector measures
#: markers inside the image, with sub-pixel centres that may reach half a pixel past its
#: edge; one pixel is the margin of the check.
IMAGE_MARGIN_PX = 1.0


def check_features_in_image(features: ArrayLike, intrinsics: StereoIntrinsics,
                            margin_px: float = IMAGE_MARGIN_PX) -> None:
    """
    Raise :class:`InputError` ('features off the image') unless p_I lies in the image.

    ``features`` (6,) as :func:`read_features` returns them (u_l, u_r, v of each marker);
    each u within [-margin, width + margin], each v within [-margin, height + margin]. For
    measured features only: an estimate F(q_T) may lie anywhere.
    """
    p = np.asarray(features, dtype=float).reshape(2, 3)
    u, v = p[:, :2], p[:, 2]
    k = intrinsics
    if (np.any(u < -margin_px) or np.any(u > k.width + margin_px)
            or np.any(v < -margin_px) or np.any(v > k.height + margin_px)):
        raise InputError('features off the image',
                         f'{p.reshape(6).tolist()} px, image {k.width} x {k.height} '
                         f'(margin {margin_px:g} px)')


class FeatureStatus(NamedTuple):
    """
    What the feature node published for one stereo frame (/ibvs/feature_status).

    The fields are the contract's :data:`ibvs_common.contract.FEATURE_STATUS_KEYS`.

    Attributes
    ----------
    mode : str
        One of :data:`ibvs_common.contract.FEATURE_MODES`: what was published.
    source : str
        What the output follows: measured or estimated.
    reason : str
        :data:`ibvs_common.contract.FEATURE_MEASURED` when the detector found both markers
        in both images, else why not.
    blend_weight : float
        Share of the switch offset still blended (0 to 1).
    search : str
        How the detector searched ('roi' or 'full').

    """

    mode: str
    source: str
    reason: str
    blend_weight: float
    search: str

    @property
    def measured(self) -> bool:
        """Return whether the detector measured the frame (eq. 2-3), blended or not."""
        return self.reason == contract.FEATURE_MEASURED


def feature_status_msg(status: FeatureStatus, stamp: Union[int, Time], name: str = '',
                       hardware_id: str = '',
                       frame_id: str = contract.CAMERA_FRAME) -> DiagnosticArray:
    """
    Return ``status`` as the /ibvs/feature_status of the frame stamped ``stamp``.

    One DiagnosticStatus (level OK, message the mode) whose values are the contract's
    keys in their order; the blend weight is written with 6 significant digits.

    Parameters
    ----------
    status : FeatureStatus
        What was published for the frame.
    stamp : int or builtin_interfaces.msg.Time
        The frame's stamp (ns, or as a message).
    name, hardware_id : str
        The DiagnosticStatus's name and hardware id (the publishing node's).
    frame_id : str
        The header's frame.

    Returns
    -------
    diagnostic_msgs.msg.DiagnosticArray
        The message.

    """
    msg = DiagnosticArray()
    msg.header.stamp = stamp if isinstance(stamp, Time) else ns_stamp(stamp)
    msg.header.frame_id = frame_id
    text = status._replace(blend_weight=f'{status.blend_weight:.6g}')
    msg.status = [DiagnosticStatus(
        level=DiagnosticStatus.OK, name=name, message=str(status.mode), hardware_id=hardware_id,
        values=[KeyValue(key=k, value=str(getattr(text, k)))
                for k in contract.FEATURE_STATUS_KEYS])]
    return msg


def read_feature_status(msg: DiagnosticArray) -> FeatureStatus:
    """
    Return the :class:`FeatureStatus` of a /ibvs/feature_status; :class:`InputError` if bad.

    Reads the first DiagnosticStatus. Refused: no status ('no status'), a key of the
    contract missing, a mode not in :data:`ibvs_common.contract.FEATURE_MODES` or a blend
    weight that is not a finite number ('malformed feature status').
    """
    if not msg.status:
        raise InputError('no status')
    values = {kv.key: kv.value for kv in msg.status[0].values}
    missing = [k for k in contract.FEATURE_STATUS_KEYS if k not in values]
    if missing:
        raise InputError('malformed feature status', f'no {", ".join(missing)}')
    if values['mode'] not in contract.FEATURE_MODES:
        raise InputError('malformed feature status', f"mode {values['mode']!r}")
    try:
        weight = float(values['blend_weight'])
    except ValueError:
        weight = math.nan
    if not math.isfinite(weight):
        raise InputError('malformed feature status',
                         f"blend_weight {values['blend_weight']!r}")
    return FeatureStatus(values['mode'], values['source'], values['reason'], weight,
                         values['search'])
