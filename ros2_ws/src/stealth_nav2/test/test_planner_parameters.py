"""The planner server's parameter table: every task number of a scene from topics is a
parameter, with the core's default (plain pytest)."""

import dataclasses

from stealth_nav2.covert_planning import TaskNumbers
from stealth_nav2.planner_parameters import PARAMETERS, TASK_PARAMETERS, task_numbers


def test_task_numbers_are_parameters_with_the_cores_defaults():
    defaults = {name: param.default for name, param in PARAMETERS.items()}
    assert task_numbers(defaults) == TaskNumbers()
    assert set(TASK_PARAMETERS) == {f.name for f in dataclasses.fields(TaskNumbers)}
    assert all(PARAMETERS[name].read_only for name in TASK_PARAMETERS)


def test_every_number_has_a_range_that_holds_its_default():
    for name, param in PARAMETERS.items():
        if isinstance(param.default, str):
            continue
        low, high = param.bounds
        assert low <= param.default <= high, name
