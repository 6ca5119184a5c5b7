"""Modules both ROS packages carry must stay the same file.

cartesian_3p_driver is installed on its own (a gantry computer needs no perception stack), so
it cannot import stereo_fuzzy_perception; the parameter helpers are therefore copied into each
package, and this test keeps the copies identical.
"""

from pathlib import Path

import pytest

REPO_ROOT = Path(__file__).resolve().parents[1]
PERCEPTION = REPO_ROOT / 'src' / 'stereo_fuzzy_perception' / 'stereo_fuzzy_perception'
DRIVER = REPO_ROOT / 'src' / 'cartesian_3p_driver' / 'cartesian_3p_driver'


@pytest.mark.parametrize('module', ['parameter_spec.py', 'ros_parameters.py'])
def test_both_packages_carry_the_same_copy(module):
    assert (PERCEPTION / module).read_text() == (DRIVER / module).read_text(), (
        f'{module} differs between the packages: change both copies together')
