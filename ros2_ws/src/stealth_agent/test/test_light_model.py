"""The light model: learns where the lights are from its steps, never from the scenario's lights,
and plans around them within a few episodes."""

import dataclasses
import math

import numpy as np
import pytest
from stealth_agent.learners import LearnerConfig, make_learner
from stealth_agent.light_model import LightModelError, LightModelLearner
from stealth_agent.policy_store import load_policy, save_policy
from stealth_agent.protocol import ProtocolAgent
from stealth_agent.state_index import StateIndex
from stealth_core.gym_env import StealthNavEnv
from stealth_core.light_world import LightWorld, StepEvidence
from stealth_core.planners import follow, value_iteration
from stealth_core.reward import EpisodeOutcome
from stealth_core.scenario import load_scenario
from stealth_core.scenario_generator import Options, generate

CONFIG = LearnerConfig.constant(gamma=1.0, epsilon=0.0)


def light_model(scenario, seed=0, index=None):
    learner = make_learner('light-model', 4, CONFIG)
    index = StateIndex() if index is None else index
    learner.attach(LightWorld(scenario), index, np.random.default_rng(seed))
    return learner, index


def play(env, agent, seed=None):
    observation, _ = env.reset(seed=seed)
    action = agent.first_action(observation)
    while True:
        observation, reward, terminated, truncated, info = env.step(action)
        if terminated:
            agent.last_action(reward)
            return info
        if truncated:
            agent.truncate(reward, observation)
            return info
        action = agent.next_action(reward, observation)


def moved(light, dx):
    """The light elsewhere (a moving one only shifted: its beam must stay inside its sweep)."""
    turn = 0.0 if light.is_moving else 1.0
    return dataclasses.replace(light, x=light.x + dx, direction=light.direction + turn)


@pytest.mark.parametrize(('name', 'episodes'), [('simple-maze', 2), ('simple-maze-moving', 1)])
def test_it_never_reads_the_lights(name, episodes):
    """The same experience with the scenario's lights removed, or moved, gives the same
    decisions and the same values: everything it knows of the lights came from its steps (where
    lights move, the world keeps only their timing)."""
    scenario = load_scenario(name)
    without = dataclasses.replace(scenario, lights=())
    elsewhere = dataclasses.replace(scenario, lights=tuple(moved(L, 0.5) for L in scenario.lights))
    env = StealthNavEnv(name)
    index = StateIndex()  # one numbering of the states for all three
    learners = []
    for world in (scenario, without, elsewhere):
        learners.append(make_learner('light-model', env.task.num_actions, CONFIG))
        learners[-1].attach(LightWorld(world), index, np.random.default_rng(3))
    agent = ProtocolAgent(learners[0], index, np.random.default_rng(1))
    for episode in range(episodes):
        observation, _ = env.reset(seed=episode)
        action = agent.first_action(observation)
        done = False
        while not done:
            row = index.lookup(observation)
            chosen = [int(np.argmax(learner.q[row])) for learner in learners]
            assert chosen[1:] == chosen[:1] * 2
            previous, taken = row, action
            observation, reward, terminated, truncated, _ = env.step(action)
            done = terminated or truncated
            following = None if terminated else index.row(observation)
            for learner in learners[1:]:
                learner.update(previous, taken, reward, following, terminated)
            if terminated:
                agent.last_action(reward)
            elif truncated:
                agent.truncate(reward, observation)
            else:
                action = agent.next_action(reward, observation)
        for learner in learners[1:]:
            learner.end_episode()
    for learner in learners[1:]:
        np.testing.assert_array_equal(learner.q, learners[0].q)
    assert learners[0].belief.evidence  # it did learn something


def test_it_reaches_the_goal_unseen_after_a_detection_or_two():
    """simple-maze: the first route runs into a light; within three episodes the greedy plan
    reaches the goal undetected, and so do the greedy rollouts after it. Training then probes
    the corridors some hypothesis still lights, and stops once they are known: its last
    episodes reach the goal too."""
    env, evaluator = StealthNavEnv('simple-maze'), StealthNavEnv('simple-maze')
    learner, index = light_model(env.task.scenario)
    agent = ProtocolAgent(learner, index, np.random.default_rng(0))
    greedy = ProtocolAgent(learner, index, np.random.default_rng(1), learning=False)
    outcomes, greedy_outcomes = [], []
    for episode in range(8):
        outcomes.append(play(env, agent, seed=episode)['outcome'])
        greedy_outcomes.append(play(evaluator, greedy, seed=episode)['outcome'])
    success = EpisodeOutcome.SUCCESS.name
    assert outcomes.count(EpisodeOutcome.DETECTED.name) <= 3, outcomes
    assert outcomes[-3:] == [success] * 3, outcomes
    assert greedy_outcomes[2:] == [success] * 6, greedy_outcomes


def test_a_used_index_and_an_unknown_rule_are_refused():
    scenario = load_scenario('simple-maze')
    index = StateIndex()
    index.row(np.array([99.0, 99.0], dtype=np.float32))
    learner = make_learner('light-model', 4, CONFIG)
    with pytest.raises(LightModelError, match='fresh index'):
        learner.attach(LightWorld(scenario), index, np.random.default_rng(0))
    with pytest.raises(LightModelError, match='rule'):
        learner.attach(LightWorld(scenario), StateIndex(), np.random.default_rng(0), rule='bold')
    with pytest.raises(LightModelError, match='attach'):
        make_learner('light-model', 4, CONFIG).update(0, 0, -1.0, 1, False)


def test_a_contradicting_step_is_reported_not_ignored():
    """The same step read as dark and as lit: no light field explains both."""
    learner, _ = light_model(load_scenario('simple-maze'))
    model = learner.world.model
    place = model.start
    learner.belief.observe(StepEvidence(place, 0, 0.0, 0.0))
    learner.belief.observe(StepEvidence(place, 0, 0.2, 0.2))
    learner.end_episode()
    assert any('direction 0' in note for note in learner.notes), learner.notes


def test_a_saved_light_model_loads_as_a_whole_policy_and_resumes(tmp_path):
    scenario = load_scenario('simple-maze')
    env = StealthNavEnv('simple-maze')
    learner, index = light_model(scenario)
    agent = ProtocolAgent(learner, index, np.random.default_rng(0))
    play(env, agent, seed=0)
    path = tmp_path / 'policy.npz'
    save_policy(path, learner, index)
    saved = load_policy(path)
    assert isinstance(saved.learner, LightModelLearner)
    assert len(saved.index) == learner.world.model.size  # every place has its row
    np.testing.assert_array_equal(saved.learner.q, learner.q)
    saved.learner.attach(LightWorld(scenario), saved.index, np.random.default_rng(0))
    assert [tuple(e) for e in saved.learner.belief.evidence] == [
        tuple(e) for e in learner.belief.evidence
    ]
    lights = np.load(path)['belief_lights']
    assert lights.shape[1] == 7 and np.all(np.isfinite(lights))
    assert not math.isnan(float(saved.learner.q.max()))


def generated(seed, tmp_path):
    """A validation building of the generator (30 x 30 m, 4 static lights) and its env."""
    path = generate(seed, Options()).write(tmp_path)
    return load_scenario(path), StealthNavEnv(str(path))


def train(scenario, env, episodes):
    """Train ``episodes`` episodes (seed 0), a greedy rollout after each: both outcome lists
    and the last greedy rollout's steps."""
    evaluator = StealthNavEnv(str(scenario.path))
    learner, index = light_model(scenario)
    agent = ProtocolAgent(learner, index, np.random.default_rng(0))
    greedy = ProtocolAgent(learner, index, np.random.default_rng(1), learning=False)
    trained, evaluated = [], []
    for episode in range(episodes):
        trained.append(play(env, agent, seed=episode)['outcome'])
        info = play(evaluator, greedy, seed=episode)
        evaluated.append(info['outcome'])
    return learner, trained, evaluated, info['steps']


def test_where_its_plan_gives_up_on_the_goal_training_probes_instead(tmp_path):
    """Validation building 100000 + 9: the first detection, by a light just behind the start,
    leaves hypotheses that block every way on (the plan would wait out the step limit: 3
    timeouts in a row, nothing learned); training follows the optimistic plan there instead,
    and the greedy plan reaches the goal."""
    scenario, env = generated(100_009, tmp_path)
    learner, trained, evaluated, _ = train(scenario, env, 4)
    timeout = EpisodeOutcome.TIMEOUT.name
    assert timeout not in trained, trained
    assert evaluated[-1] == EpisodeOutcome.SUCCESS.name, evaluated
    model = learner.world.model
    assert model.goal[follow(model, lambda place: int(np.argmax(learner.q[place])))[-1]]


def test_after_a_success_it_tests_the_shorter_route_some_hypothesis_lights(tmp_path):
    """Validation building 100006: the posterior's plan reaches the goal by a route 1.2x the
    optimum's, round a corridor some weighed hypothesis lights, and would never test it; a
    probe episode after a success walks it, and the greedy route ends within 1.1x."""
    scenario, env = generated(100_006, tmp_path)
    _, _, evaluated, steps = train(scenario, env, 7)
    model = LightWorld(scenario).model
    optimum = value_iteration(StealthNavEnv(str(scenario.path)).model)
    shortest = len(follow(model, lambda i: int(optimum.policy[i]))) - 1
    assert evaluated[-1] == EpisodeOutcome.SUCCESS.name, evaluated
    assert steps <= 1.1 * shortest, (steps, shortest)


def test_a_step_read_detected_once_and_dark_once_is_planned_as_often_detected():
    """Through ROS a step beside a beam's edge reads lit or dark by where the true pose stopped:
    the plan takes it as detected as often as it was (in-process a step always reads the same),
    its light as its dark readings', whatever the particles say; cautious and optimistic take
    it as detected and as dark."""
    learner, _ = light_model(load_scenario('simple-maze'))
    place, direction = learner.world.model.start, 0
    for low, high in ((0.1, 0.1), (learner.world.threshold, math.inf), (0.2, 0.2)):
        learner.belief.observe(StepEvidence(place, direction, low, high))
    for rule, detected in (('expected', 1 / 3), ('cautious', 1.0), ('optimistic', 0.0)):
        p_detected, light = learner.planned_visibility(rule)
        assert p_detected[place, direction] == pytest.approx(detected), rule
        assert light[place, direction] == pytest.approx(0.15), rule
    other = learner.planned_visibility('expected')[0]
    assert np.count_nonzero(other) == 1  # no other step was read


def test_with_a_plan_margin_a_step_lit_just_below_the_threshold_is_planned_as_detected():
    """Through ROS one step's readings spread by a few per cent: a step read at 0.28 against a
    threshold of 0.3 is taken as detected by a plan with a 10 % margin, as dark without one."""
    scenario = load_scenario('simple-maze')
    for margin, detected in ((0.0, 0.0), (0.1, 1.0)):
        learner = make_learner('light-model', 4, CONFIG)
        world = LightWorld(scenario)
        learner.attach(world, StateIndex(), np.random.default_rng(0), plan_margin=margin)
        place = world.model.start
        learner.belief.observe(StepEvidence(place, 0, 0.28, 0.28))
        assert learner.planned_visibility('expected')[0][place, 0] == detected
    with pytest.raises(LightModelError, match='plan_margin'):
        learner.attach(world, StateIndex(), np.random.default_rng(0), plan_margin=1.0)
