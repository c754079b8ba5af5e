"""`stealth rollout`: which saved policy it runs, on which scenario and goal (the training run's,
or the ones the policy file names), checked before anything starts: by name (the title) and by
content (the map's grid and the lights, as the policy file records them). No rclpy.
"""

from __future__ import annotations

from pathlib import Path
import re
import subprocess
import sys

from stealth_bringup.run_config import (
    RunConfigError,
    check_goal,
    load_run_scenario,
    relative_to_cwd,
)

# A differing content hash of the policy file (policy_store.CONTENT_KEYS), in words.
CONTENT_WORDS = {'grid_sha256': 'a different map', 'lights_sha256': 'different lights'}
_TITLE = re.compile(r'^stealth-nav: (?P<scenario>.+) \((?P<goal>[^()]+)\)$')


def rollout_source(args):
    """(scenario, goal, policy path, params dir, notes) of `stealth rollout`."""
    if getattr(args, 'learner', None) is not None:
        return plugin_source(args)
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
    from stealth_core.task import StealthTask

    expected = StealthTask(scenario, goal).title
    if title and title != expected:
        raise RunConfigError(
            f'{policy} was trained on {title!r}, not on {expected!r}; give the matching '
            '--scenario and --goal'
        )
    return scenario, goal, policy, params_dir, same_content(policy, saved.scenario, scenario)


def same_content(policy: Path, saved: dict, scenario) -> list[str]:
    """RunConfigError when the policy was learned on another map or under other lights than
    the scenario's (a file that kept its name); a note to say when the policy file records
    neither (saved before they were), and only the name could be compared."""
    from stealth_agent.policy_store import content_differences
    from stealth_core.scenario import content_identity

    keys = content_differences(saved, content_identity(scenario))
    if keys is None:
        return [
            f'{policy} records no map or lights hash (saved before policies did): only its '
            f'scenario name is checked, not whether {relative_to_cwd(scenario.path)} still has '
            'the map and lights it was trained on'
        ]
    differ = [CONTENT_WORDS[key] for key in keys]
    if differ:
        raise RunConfigError(
            f'{policy} was trained on scenario {scenario.name!r} with {" and ".join(differ)} '
            f'than {relative_to_cwd(scenario.path)} has now (the same name, other content): '
            'give --scenario the scenario file it was trained on, or train a policy on this one'
        )
    return []


# The plugin's load in a child process: it may import JAX, which is multithreaded and must not
# be in the orchestrator's process when it forks the nodes (JAX warns of deadlocks).
_LOAD_PLUGIN = (
    'import sys\n'
    'from stealth_agent.policy_plugins import PluginError, load_policy\n'
    'try:\n'
    '    policy = load_policy(sys.argv[1], sys.argv[2])\n'
    "    if hasattr(policy, 'check_scenario'):\n"
    '        policy.check_scenario(sys.argv[3])\n'
    '    print(policy.path)\n'
    'except (PluginError, ValueError) as error:\n'
    '    sys.exit(str(error))\n'
)
PLUGIN_CHECK_TIMEOUT = 120.0  # s: importing JAX and reading the weights on a loaded machine


def plugin_source(args):
    """(scenario, goal, weights path, params dir, notes) of `stealth rollout --learner NAME`:
    the plugin loads its weights and checks the scenario before anything starts (in a child
    process), so a missing extra, a bad weights file or a scenario it cannot play stops the
    run in one line (naming what to install, the path, or the weights and the scenario)."""
    if args.scenario is None:
        raise RunConfigError(
            f'--learner {args.learner}: give --scenario (any its weights can play)'
        )
    scenario = load_run_scenario(args.scenario)
    goal = check_goal(scenario, args.goal, None)
    command = [
        sys.executable,
        '-c',
        _LOAD_PLUGIN,
        args.learner,
        args.policy or '',
        str(scenario.path),
    ]
    try:
        done = subprocess.run(
            command, capture_output=True, text=True, timeout=PLUGIN_CHECK_TIMEOUT, check=False
        )
    except subprocess.TimeoutExpired:
        raise RunConfigError(
            f'--learner {args.learner}: loading it took over {PLUGIN_CHECK_TIMEOUT:g} s'
        ) from None
    if done.returncode != 0:
        lines = done.stderr.strip().splitlines() or [f'exit code {done.returncode}']
        raise RunConfigError(f'--learner {args.learner}: {lines[-1]}')
    return scenario, goal, Path(done.stdout.strip().splitlines()[-1]), args.params_dir, []


def check_plugin_grid(scenario, goal: str, learner: str, track: str) -> None:
    """RunConfigError, one line, where the environment would have no grid to send the plugin
    on ``track`` (``grid_observation.check_grid``: the sensed track with moving lights, or
    exposure), before anything starts rather than at the environment's startup."""
    from stealth_core.grid_observation import check_grid
    from stealth_core.task import StealthTask

    try:
        check_grid(StealthTask(scenario, goal), track)
    except ValueError as error:
        raise RunConfigError(f'--learner {learner}: environment.track {track}: {error}') from None
