"""
A run's results written: ``metrics.json`` and the figures, from its bag.

``ibvs run`` writes them as soon as its run has stopped, ``ibvs analyse`` again from a bag
(:func:`write_results`); the feature figures compare against the target features the
controller servoed to (:func:`target_features`), as the film does.
"""

from collections.abc import Callable
import json
from pathlib import Path
from typing import Any

from ibvs_bringup.recorder import recover
from ibvs_common import shared_params
from ibvs_model import CameraRobotModel, inverse_kinematics, IRB4600
import numpy as np
from numpy.typing import NDArray

from . import analysis


def target_features(run: analysis.RunData) -> NDArray[np.float64] | None:
    """
    Return the target features the controller servoed to, for the feature figures.

    A taught run (``target_features_source: taught``): the features the feature node
    measured on the teach pair (:attr:`.analysis.RunData.taught_target`), which the
    controller used; F(q_target) would differ from them by the camera model's errors (a
    constant error in ``feature_error.png`` the controller never saw). Otherwise F(q_target)
    with the recorded camera and the nominal robot (None without a camera).
    """
    if shared_params.taught(run.params) and \
            run.taught_target is not None:
        return run.taught_target
    if run.camera is None:
        return None
    q = inverse_kinematics(run.target)
    return CameraRobotModel(run.camera, IRB4600).features(q)


def write_results(bag_path: str | Path, out_dir: str | Path,
                  wall_duration_s: float | None = None, figures: bool = True,
                  on_metrics: Callable[[dict[str, Any]], None] | None = None
                  ) -> dict[str, Any]:
    """
    Analyse a bag: write ``metrics.json`` and the figures into ``out_dir``; return metrics.

    ``on_metrics(metrics)`` is called once ``metrics.json`` is written, before the figures
    (matplotlib takes seconds): ``ibvs run`` prints the metrics then.
    """
    out_dir = Path(out_dir)
    recover(bag_path)  # the bag of a runner that was killed: readable again
    run, metrics = analysis.analyse_bag(bag_path)
    if wall_duration_s is not None:
        metrics['wall_duration_s'] = wall_duration_s
        metrics['real_time_factor'] = metrics['sim_duration_s'] / wall_duration_s
    metrics['bag'] = str(bag_path)
    (out_dir / 'metrics.json').write_text(json.dumps(metrics, indent=2) + '\n')
    if on_metrics is not None:
        on_metrics(metrics)
    if not figures:
        return metrics
    from . import plots  # here: matplotlib costs seconds of start-up
    plots.write_all(run, out_dir, target_features(run))
    if len(run.joints[0]):  # read and limited once, by analyse_bag
        plots.joints(run.joints, run.joint_limits, out_dir / 'joints.png', plots.title_of(run))
    return metrics
