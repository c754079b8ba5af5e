"""The planner server's goal queue: one goal runs, the others wait their turn in the order they
came, at most ``capacity`` of them; a cancelled goal leaves the queue (plain pytest)."""

import pytest
from stealth_nav2.goal_queue import GoalQueue


def test_goals_run_one_at_a_time_in_the_order_they_came():
    queue = GoalQueue(capacity=10)
    goals = [object() for _ in range(4)]
    assert [queue.arrive(goal) for goal in goals] == [True, False, False, False]
    assert queue.running is goals[0] and len(queue) == 3
    ran = [goals[0]]
    while (following := queue.finish(ran[-1])) is not None:
        ran.append(following)
    assert ran == goals
    assert queue.running is None and len(queue) == 0
    assert queue.arrive(goals[0])  # idle again: runs at once


def test_capacity_counts_the_waiting_goals_only():
    queue = GoalQueue(capacity=2)
    assert not queue.full
    queue.arrive('a')
    assert not queue.full  # 'a' runs; two may wait
    queue.arrive('b')
    queue.arrive('c')
    assert queue.full
    with pytest.raises(ValueError, match='full: 2 waiting'):
        queue.arrive('d')
    queue.capacity = 3  # the parameter raised at run time
    assert not queue.full
    assert GoalQueue(capacity=0).arrive('alone')  # 0: nothing waits, but one runs


def test_a_withdrawn_goal_leaves_the_queue_and_its_end_starts_nothing():
    queue = GoalQueue(capacity=5)
    a, b, c = object(), object(), object()
    for goal in (a, b, c):
        queue.arrive(goal)
    assert queue.withdraw(b)
    assert not queue.withdraw(b)  # gone already
    assert not queue.withdraw(a)  # running, not waiting
    assert queue.finish(b) is None  # the withdrawn goal ends: not the one running
    assert queue.running is a
    assert queue.finish(a) is c
