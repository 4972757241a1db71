"""feature_error.png of a taught run compares against the taught target the controller used."""

from ibvs_analysis import analysis, results
import numpy as np


def _run(source, taught):
    return analysis.RunData(params={'target_features_source': source}, run_info={},
                            t=np.zeros(2), position=np.zeros((2, 3)),
                            rotation=np.tile(np.eye(3), (2, 1, 1)), target=np.eye(4),
                            taught_target=taught)


def test_the_last_taught_value_on_diagnostics_is_read():
    assert analysis._taught([]) is None
    assert analysis._taught(['[1, 2, 3, 4, 5, 6]', '[640.5, 630.25, 360, 641, 631, 380.125]']) \
        .tolist() == [640.5, 630.25, 360.0, 641.0, 631.0, 380.125]
    assert analysis._taught(['[1, 2]']) is None and analysis._taught(['nan-ish']) is None


def test_a_taught_run_is_compared_with_its_taught_target():
    taught = np.arange(6.0)
    assert results.target_features(_run('taught', taught)) is taught
    # A model run (and a taught one without the value: an older bag) keep F(q_target),
    # which needs the recorded camera: none here.
    assert results.target_features(_run('model', taught)) is None
    assert results.target_features(_run('taught', None)) is None
