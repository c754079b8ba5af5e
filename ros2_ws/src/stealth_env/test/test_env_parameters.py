"""The environment's parameter table: the checks rclpy cannot make, and the topics robot's
settings."""

from types import SimpleNamespace

from stealth_env.env_parameters import PARAMETERS, not_a_choice, topic_config


def change(name, value):
    return SimpleNamespace(name=name, value=value)


def test_a_parameter_with_choices_takes_only_those():
    assert not_a_choice([change('judge_on', 'estimate'), change('move_timeout', 5.0)]) is None
    assert (
        not_a_choice([change('robot_interface', 'topics'), change('reset_mode', 'drive')]) is None
    )
    assert not_a_choice([change('judge_on', 'true'), change('reset_mode', 'fly')]) == (
        "reset_mode must be one of teleport, drive, got 'fly'"
    )


def test_the_topics_robot_settings_come_from_the_parameters():
    values = {name: param.default for name, param in PARAMETERS.items()}
    values.update(max_linear_speed=0.3, bump_distance=0.1, stall_time=2.0)
    config = topic_config(values, robot_radius=0.25)
    assert config.limits.max_linear_speed == 0.3
    assert config.limits.max_angular_accel == PARAMETERS['max_angular_accel'].default
    assert (config.robot_radius, config.bump_distance, config.stall_time) == (0.25, 0.1, 2.0)
