"""
The feature node's lockstep rule (docs/design.md §4), plain code without rclpy.

Left and right images are paired by stamp, each pair matched with the joint state at its
stamp (interpolated between the two that bracket it: :class:`ibvs_common.sync.JointTrack`),
and a frame that never can be complete is dropped with a reason. Used by
:mod:`.feature_node`, which decodes, detects, publishes and counts.

- :class:`StereoPairer`: the rule;
- :class:`Drop`, :class:`Wait`, :class:`Ready`: what :meth:`StereoPairer.poll` says of
  each pending frame.
"""

from typing import Any, Dict, Iterator, List, NamedTuple, Optional, Tuple, Union

from ibvs_common.sync import JointTrack, Rejection


class Drop(NamedTuple):
    """A stereo frame that will never be complete: counted with ``reason``."""

    t_ns: int
    reason: str
    detail: str


class Wait(NamedTuple):
    """A stereo frame still waiting for the inputs named in ``waiting``."""

    t_ns: int
    waiting: List[str]


class Ready(NamedTuple):
    """A complete stereo frame: the images by side and the joint state of its exposure."""

    t_ns: int
    images: Dict[str, Any]
    joints: Any


class _Frame:
    """Both images of one stamp as they arrive; ``rejected`` once one image was refused."""

    __slots__ = ('images', 'rejected')

    def __init__(self) -> None:
        self.images: Dict[str, Any] = {}
        self.rejected: bool = False


class StereoPairer:
    """
    Left and right images paired by stamp, each pair matched with its joint state.

    A frame is complete when both images of its stamp and its joint state are here: the
    state at its stamp, read from the joint states by :class:`ibvs_common.sync.JointTrack`
    (the state stamped exactly then, as the simulator's lockstep publishes it with the
    frame, or the interpolation between the two that bracket it, as a real cell's
    joint_state_broadcaster publishes on its own cycle). It is dropped when it never can
    be: the other side's images moved past it (left/right stamp mismatch), its joint state
    cannot be had (no state before it, its own state rejected, a gap wider than the
    measured rate allows), or it fell ``stale_timeout_ns`` behind the newest input.
    Newer frames supersede older ones still waiting. Images older than the last
    frame published or ``stale_timeout_ns`` behind the newest input are refused.

    Parameters
    ----------
    stale_timeout_ns : int
        How far (ns) an input may lag the newest one (the node's ``stale_timeout_s``).
    history_ns : int
        How long (ns) joint states are kept behind the newest input (``joint_history_s``).
    sides : tuple of str
        The two image sources, in the order the texts name them.

    """

    def __init__(self, stale_timeout_ns: int, history_ns: int,
                 sides: Tuple[str, str] = ('left', 'right')) -> None:
        """Create the pairer with nothing received (see the class docstring)."""
        self.stale_timeout_ns = stale_timeout_ns
        self.sides = sides
        self._frames: Dict[int, _Frame] = {}
        #: The joint states kept, read at each frame's stamp.
        self.joints: JointTrack[Any] = JointTrack(horizon_ns=history_ns, strict=False)
        self._newest_image = {side: -1 for side in sides}
        #: The newest stamp of any input (images and joint states).
        self.newest_ns = -1
        #: The stamp of the last frame published (:meth:`published`).
        self.last_published_ns = -1
        #: How long (ns) after its exposure a frame is stamped: its joint state is read at
        #: stamp - offset (the feature node's estimate, :mod:`.stamp_offset`; 0: the stamp
        #: is the exposure).
        self.exposure_offset_ns = 0

    def forget(self) -> None:
        """Forget every frame, state and stamp (the clock jumped back: a new time line)."""
        self._frames.clear()
        self.joints.forget()
        self._newest_image = {side: -1 for side in self.sides}
        self.newest_ns = self.last_published_ns = -1

    def __len__(self) -> int:
        """Return the number of frames pending (incomplete or refused, not yet forgotten)."""
        return len(self._frames)

    def _seen(self, t_ns: int) -> None:
        self.newest_ns = max(self.newest_ns, t_ns)

    def offer_image(self, side: str, t_ns: int, image: Any,
                    error: Optional[Rejection] = None) -> Optional[Rejection]:
        """
        Take the ``side`` image stamped ``t_ns``; return why it is refused, or None.

        Parameters
        ----------
        side : str
            One of :attr:`sides`.
        t_ns : int
            Its stamp (ns).
        image
            The decoded image, handed back by :class:`Ready`.
        error : Rejection, optional
            Why the node could not decode it: the frame is then refused as well.

        Returns
        -------
        Rejection or None
            ``error``, 'out of order' (not after the last frame published) or 'stale';
            the frame of a refused image is skipped, its other image dropped silently.

        """
        self._seen(t_ns)
        self._newest_image[side] = max(self._newest_image[side], t_ns)
        rejection = error
        if rejection is None and t_ns <= self.last_published_ns:
            rejection = Rejection('out of order', f'stamp {t_ns} ns is not after the last '
                                  f'published frame {self.last_published_ns} ns')
        if rejection is None and self.newest_ns - t_ns > self.stale_timeout_ns:
            rejection = Rejection('stale', f'{(self.newest_ns - t_ns) * 1e-9:.3f} s behind '
                                  'the newest input')
        frame = self._frames.setdefault(t_ns, _Frame())
        if rejection is not None:
            frame.rejected = True
            frame.images.clear()
        elif not frame.rejected:
            frame.images[side] = image
        return rejection

    def offer_joints(self, t_ns: int, joints: Any) -> None:
        """Keep the joint state stamped ``t_ns`` (a late one is inserted in order)."""
        self._seen(t_ns)
        self.joints.add(t_ns, joints)
        self.joints.prune(self.newest_ns)

    def offer_bad_joints(self, t_ns: int, reason: str) -> None:
        """Note that the joint state stamped ``t_ns`` was rejected for ``reason``."""
        self._seen(t_ns)
        self.joints.add_bad(t_ns, reason)
        self.joints.prune(self.newest_ns)

    def published(self, t_ns: int) -> None:
        """Note that the frame at ``t_ns`` was published: older images are out of order."""
        self.last_published_ns = t_ns

    def joints_at(self, t_ns: int) -> Tuple[Any, Optional[str]]:
        """Return the joints of the frame at ``t_ns``, as :meth:`JointTrack.at` says."""
        return self.joints.at(t_ns)

    def poll(self, blocker: Optional[str] = None) -> Iterator[Union[Drop, Wait, Ready]]:
        """
        Decide every pending frame, oldest first; yield what became of each.

        Parameters
        ----------
        blocker : str, optional
            What else the node still waits for (e.g. its camera model): a complete frame
            then waits too, and a frame that times out names it.

        Yields
        ------
        Drop, Wait or Ready
            :class:`Drop` for a frame that never can be complete and for each older frame
            a :class:`Ready` one supersedes (before it); :class:`Wait` for a frame still
            waiting; :class:`Ready` for a complete frame, which leaves the pairer.
            A refused frame is forgotten without a word once both sides moved past it.

        """
        for t_ns in sorted(self._frames):
            frame = self._frames.get(t_ns)
            if frame is None:
                continue
            if frame.rejected:
                # Already counted when its image was refused; forget it once both came.
                if all(self._newest_image[s] >= t_ns for s in self.sides) \
                        or self.newest_ns - t_ns > self.stale_timeout_ns:
                    del self._frames[t_ns]
                continue
            drop = None
            missing = [s for s in self.sides if s not in frame.images]
            for side in missing:
                if self._newest_image[side] > t_ns:
                    other = self.sides[1] if side == self.sides[0] else self.sides[0]
                    drop = ('left/right stamp mismatch',
                            f'{other} image at {t_ns * 1e-9:.9f} s has no {side} image')
            joints, why = self.joints_at(t_ns - self.exposure_offset_ns)
            if drop is None and why is not None:
                drop = ('no joint state', why)
            waiting = [f'{s} image' for s in missing] + (['joint state'] if joints is None
                                                         else [])
            waiting += [blocker] if blocker else []
            if drop is None and self.newest_ns - t_ns > self.stale_timeout_ns:
                drop = ('timed out', f'frame at {t_ns * 1e-9:.9f} s waited for '
                        + ', '.join(waiting))
            if drop is not None:
                if missing and drop[0] != 'timed out':
                    # its other image may still come: absorbed without a word
                    frame.rejected = True
                    frame.images.clear()
                else:
                    del self._frames[t_ns]
                yield Drop(t_ns, *drop)
                continue
            if missing or joints is None or blocker:
                yield Wait(t_ns, waiting)
                continue
            del self._frames[t_ns]
            for older in [t for t in self._frames if t < t_ns]:
                del self._frames[older]
                yield Drop(older, 'superseded',
                           f'frame at {older * 1e-9:.9f} s overtaken by a newer one')
            yield Ready(t_ns, frame.images, joints)
