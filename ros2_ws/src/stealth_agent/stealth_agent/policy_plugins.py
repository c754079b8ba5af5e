"""Policies from other packages, found as plugins: the agent runs a trained policy that this
package cannot import (the layering of tests/test_imports.py: the agent stands alone on the
messages), as ros2cli finds its verbs.

A package registers a policy in the entry-point group ``stealth_agent.policies`` (setup.py)::

    entry_points={'stealth_agent.policies': ['generalist = stealth_learn.ros_policy:load']}

and the agent parameter ``agent`` then takes its name (``agent: generalist``). The protocol:

- ``load(path: str) -> policy``: the weights at ``path`` ('' = the plugin's own default, e.g.
  the weights its package ships). A missing, corrupt or foreign file raises ValueError or
  OSError, one line naming the path.
- ``policy.path``: the weights file it loaded (a run records it);
- ``policy.layout``: the observation layout it reads (e.g. ``stealth-grid-v1/full``);
  ``policy.check(layout)``: ValueError, one line naming both, unless it reads the environment's
  layout (GridObservation.layout, e.g. ``stealth-grid-v1/full/40x60``).
- ``policy.check_scenario(path)`` (optional): ValueError, one line naming the weights and the
  scenario file, for a scenario the policy cannot play (the generalist: static weights given
  moving lights, time-aware ones given static lights or another cycle); `stealth rollout
  --learner` asks it before anything starts.
- ``policy(observation) -> int``: the action for one observation, a float32 (rows, cols,
  channels) array in GridObservation's layout with the robot's cell set, or (layers, rows,
  cols, channels) for a phased grid with the robot's cell set at its phase's layer. A policy
  that depends on the static channels only through a plan caches it (the agent's decision
  time).

Plain Python (importlib.metadata); no rclpy.
"""

from __future__ import annotations

import functools
from importlib import metadata

GROUP = 'stealth_agent.policies'
INSTALL_HINT = 'make learn (the learning extra: jax, flax, optax)'


class PluginError(ValueError):
    """A policy plugin that is not installed, cannot be imported or refuses its weights."""


@functools.cache
def plugin_names() -> tuple[str, ...]:
    """The names registered in GROUP (read once per process)."""
    return tuple(sorted(entry.name for entry in metadata.entry_points(group=GROUP)))


def is_plugin(name: str) -> bool:
    return name in plugin_names()


def load_policy(name: str, path: str):
    """The policy of plugin ``name`` with the weights at ``path`` ('' its default); PluginError,
    one line: a plugin not registered, one whose extra is missing (naming what to install), or
    weights it refuses (its own line, naming the path)."""
    entries = [e for e in metadata.entry_points(group=GROUP) if e.name == name]
    if not entries:
        known = ', '.join(plugin_names()) or 'none installed'
        raise PluginError(
            f'no policy plugin {name!r} in entry-point group {GROUP} ({known}): install the '
            f'package that provides it (the generalist: stealth_learn, built by make setup, '
            f'with {INSTALL_HINT})'
        )
    entry = entries[0]
    try:
        load = entry.load()
    except ImportError as error:
        text = str(error).splitlines()[0] if str(error) else type(error).__name__
        hint = '' if 'make learn' in text else f'; install it with {INSTALL_HINT}'
        raise PluginError(
            f'policy plugin {name!r} ({entry.value}) cannot be imported: {text}{hint}'
        ) from None
    try:
        return load(path)
    except (OSError, ValueError) as error:
        raise PluginError(f'policy plugin {name!r}: {error}') from None
