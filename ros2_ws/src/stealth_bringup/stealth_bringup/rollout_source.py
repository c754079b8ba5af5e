"""`stealth rollout`: which saved policy it runs, on which scenario and goal (the training run's,
or the ones the policy file names), checked before anything starts. No rclpy.
"""

from __future__ import annotations

from pathlib import Path
import re

from stealth_bringup.run_config import RunConfigError, check_goal, load_run_scenario

_TITLE = re.compile(r'^stealth-nav: (?P<scenario>.+) \((?P<goal>[^()]+)\)$')


def rollout_source(args):
    """(scenario, goal, policy path, params dir) of `stealth rollout`."""
    from stealth_agent.policy_store import PolicyFileError, load_policy

    from stealth_bringup.run_outputs import read_run_summary

    run_summary = {}
    params_dir = args.params_dir
    if args.run is not None:
        run = Path(args.run)
        if not run.is_dir():
            raise RunConfigError(f'--run {run}: no such run directory')
        policy = run / 'policy.npz'
        if not policy.is_file():
            raise RunConfigError(f'--run {run}: it has no policy.npz (did the run save one?)')
        run_summary = read_run_summary(run)
        if params_dir is None and (run / 'params').is_dir():
            params_dir = str(run / 'params')
    else:
        policy = Path(args.policy)
        if not policy.is_file():
            raise RunConfigError(f'--policy {policy}: no such file')
        run_summary = read_run_summary(policy.parent)
    try:
        saved = load_policy(policy)
    except PolicyFileError as error:
        raise RunConfigError(str(error)) from None
    title = str(saved.scenario.get('title', ''))
    named = _TITLE.match(title)
    scenario_name = (
        args.scenario
        or run_summary.get('scenario', {}).get('path')
        or (named.group('scenario') if named else None)
    )
    if scenario_name is None:
        raise RunConfigError(f'{policy}: it names no scenario; give --scenario')
    scenario = load_run_scenario(scenario_name)
    default_goal = run_summary.get('goal') or (named.group('goal') if named else None)
    goal = check_goal(scenario, args.goal, default_goal)
    from stealth_env.task import StealthTask

    expected = StealthTask(scenario, goal).title
    if title and title != expected:
        raise RunConfigError(
            f'{policy} was trained on {title!r}, not on {expected!r}; give the matching '
            '--scenario and --goal'
        )
    return scenario, goal, policy, params_dir
