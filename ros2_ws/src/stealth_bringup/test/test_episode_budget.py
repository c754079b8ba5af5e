"""stealth train's default episode budget follows the scenario's state count (no ROS)."""

from stealth_bringup.episode_budget import budget_for, default_episode_budget, state_actions
from stealth_bringup.run_arguments import DEFAULT_EPISODES, train_parser
from stealth_bringup.run_config import load_run_scenario
from stealth_bringup.run_plan import make_plan


def plan_of(*argv, runs_dir):
    args = train_parser().parse_args([*argv, '--runs-dir', str(runs_dir)])
    return make_plan(args, 'train', ['stealth', 'train', *argv])


def test_the_table_size_counts_nodes_phases_headings_and_actions():
    static, moving, exposure = (
        state_actions(load_run_scenario(name), None)
        for name in ('simple-maze', 'simple-maze-moving', 'map1-exposure')
    )
    assert static == 603 * 4  # simple-maze's lattice nodes x 4 moves
    assert moving == 603 * 8 * 5  # x 8 phase bins, and a fifth action: wait
    assert exposure == 1109 * 4 * 6  # map1's nodes x 4 headings x (4 moves, 2 turns)


def test_one_episode_per_six_state_actions_rounded_and_never_below_the_default():
    assert budget_for(603 * 4) == DEFAULT_EPISODES == 400
    assert budget_for(603 * 8 * 5) == 4000
    assert budget_for(2941 * 8 * 5) == 19_600
    assert budget_for(10) == DEFAULT_EPISODES
    budgets = [budget_for(pairs) for pairs in range(0, 200_000, 997)]
    assert budgets == sorted(budgets)  # more states never get fewer episodes


def test_a_run_without_episodes_gets_its_scenarios_budget_and_says_so(tmp_path):
    plan = plan_of('--scenario', 'simple-maze-moving', runs_dir=tmp_path / 'a')
    assert (plan.episodes, plan.goal) == (4000, 'hard')
    assert default_episode_budget(plan.scenario, plan.goal) == (4000, 24_120)
    assert any(note.startswith('episode budget 4000: one per 6 of') for note in plan.notes)
    default = plan_of(runs_dir=tmp_path / 'b')  # simple-maze, easy: as before, unsaid
    assert default.episodes == DEFAULT_EPISODES
    assert not any('budget' in note for note in default.notes)
    given = plan_of(
        '--scenario', 'simple-maze-moving', '--episodes', '50', runs_dir=tmp_path / 'c'
    )
    assert given.episodes == 50 and not any('budget' in note for note in given.notes)


def test_a_discounting_agent_is_told_the_criterion_is_undiscounted_where_lights_move(tmp_path):
    moving = ('--scenario', 'simple-maze-moving', '--episodes', '50', '--prior', 'none')
    plan = plan_of(*moving, '--set', 'agent.gamma=0.99', runs_dir=tmp_path / 'a')
    assert plan.notes == [
        'agent gamma 0.99: the success criterion judges against the undiscounted optimum, '
        'which a discounting learner may not converge to where lights move'
    ]
    assert plan_of(*moving, '--set', 'agent.gamma=1.0', runs_dir=tmp_path / 'b').notes == []
    # Still lights: the discounted and undiscounted optima are the same route (path_scores).
    still = plan_of('--set', 'agent.gamma=0.99', '--prior', 'none', runs_dir=tmp_path / 'c')
    assert still.notes == []
