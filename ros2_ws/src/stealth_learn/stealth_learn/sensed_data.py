"""The sensed track's training data (moving lights): what the robot believes along its own
episodes, labelled with what the lights-known optimum does (DAgger, Ross et al. 2011, with
value iteration as the expert).

A snapshot is one moment of an episode on the sensed Gym env: the phased belief the time-aware
network reads then (``GeneralistAgent.grid``: ``belief.believed_phased`` of the robot's phased
memory, its age channel 1 where a layer's node was never sensed) with the building's dense
targets (``generalist_data.sample_of``: the layered value iteration's optimal actions on the
lights as they are, at every cell of every layer). So the network learns to act, from what it
has sensed, as the robot that knows the lights would; the robot's own (layer, cell), where
the decision is taken, weighs ``robot_weight`` times more. With ``robot_only`` it is the only
label of a snapshot: the dense labels elsewhere teach the optimum's action at places the belief
cannot tell apart (most of them never sensed), and the network then fits those averages.

    buildings = load_buildings(seeds, options, directory)     # [(scenario, Sample)]
    samples = snapshots(buildings, policy_of, every=8)        # policy_of(scenario) -> policy

The episodes are played by ``policy_of(scenario)`` (a ``GeneralistPolicy``): the hand-set twin
first, then the network being trained (DAgger's rounds: the states its own decisions lead to).
"""

from __future__ import annotations

import dataclasses
from pathlib import Path

import numpy as np
from stealth_core.grid_observation import AGE, FREE
from stealth_core.gym_env import StealthNavEnv
from stealth_core.scenario_generator import Options

from stealth_learn import generalist_data as data
from stealth_learn.generalist_agent import GeneralistAgent


def load_buildings(seeds, options: Options, directory: Path, log=None) -> list:
    """[(scenario, Sample)] of ``seeds`` whose lights move (a seed the generator cannot prove,
    or whose lights stand still, is skipped, and said)."""
    out = []
    for seed, scenario in data.scenarios_of(seeds, options, directory, log):
        if not scenario.has_moving_lights:
            if log:
                log(f'seed {seed}: skipped (its lights are not moving)')
            continue
        out.append((scenario, data.sample_of(seed, scenario)))
    return out


def episode_snapshots(
    scenario, sample, policy, every: int, robot_weight: float, robot_only: bool = False
) -> list:
    """The snapshots (``Sample``s) of one greedy episode of ``policy`` on the sensed track of
    ``scenario``: at its first state and every ``every`` steps after (``robot_only``: labelled
    at the robot's (layer, cell) alone, with the building's weight there)."""
    env = StealthNavEnv(scenario, track='sensed')
    agent = GeneralistAgent(policy, env)
    nodes = agent.nodes
    observation, _ = env.reset(seed=sample.seed)
    out, step = [], 0
    while True:
        if step % every == 0:
            layer, node = divmod(int(env.node), nodes)
            at = (layer, agent.row[node], agent.col[node])
            weight = np.zeros_like(sample.weight) if robot_only else sample.weight.copy()
            weight[at] = sample.weight[at] * (1.0 + robot_weight)
            out.append(dataclasses.replace(sample, grid=agent.grid(observation), weight=weight))
        observation, _, terminated, truncated, _ = env.step(agent.act(observation))
        step += 1
        if terminated or truncated:
            return out


def snapshots(
    buildings,
    policy_of,
    every: int = 8,
    robot_weight: float = 20.0,
    bar=None,
    robot_only: bool = False,
):
    """Every building's episode snapshots (``episode_snapshots``), the episode played by
    ``policy_of(scenario)``; ``bar``: a tqdm to advance per building."""
    out = []
    for scenario, sample in buildings:
        policy = policy_of(scenario)
        out.extend(episode_snapshots(scenario, sample, policy, every, robot_weight, robot_only))
        if bar is not None:
            bar.update(1)
    return out


def unknown_share(samples) -> float:
    """The share of free (layer, cell)s never sensed in the snapshots (how much the network
    reads from its prior rather than from what it saw)."""
    free = sum(float((s.grid[..., FREE] > 0.5).sum()) for s in samples)
    unknown = sum(float((s.grid[..., AGE] > 0.5).sum()) for s in samples)
    return unknown / max(free, 1.0)
