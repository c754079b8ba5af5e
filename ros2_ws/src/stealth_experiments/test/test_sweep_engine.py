"""The sweep driver's guards, without Ray: an --address that is not a Ray head is refused at
once, and SIGINT or SIGTERM become Interrupted (exit 130 or 143) after Tune's run returns."""

import contextlib
import http.server
import os
import signal
import socket
import threading
import time

import pytest
from stealth_experiments import sweep_stop
from stealth_experiments.sweep import failed_runs
from stealth_experiments.sweep_engine import EngineError, check_address
from stealth_experiments.sweep_plan import make_trial
from stealth_experiments.sweep_pool import Progress, lost_records, scenarios_of
from stealth_experiments.sweep_report import SweepStore
from stealth_experiments.sweep_trials import objective, ros_settled


@pytest.fixture
def http_server():
    """A web server on a free loopback port (what a wrong --address finds)."""
    server = http.server.HTTPServer(('127.0.0.1', 0), http.server.SimpleHTTPRequestHandler)
    thread = threading.Thread(target=server.serve_forever, daemon=True)
    thread.start()
    yield f'127.0.0.1:{server.server_address[1]}'
    server.shutdown()
    server.server_close()


def test_an_address_where_a_web_server_listens_is_not_a_ray_head(http_server):
    started = time.monotonic()
    with pytest.raises(EngineError) as error:
        check_address(http_server)
    message = str(error.value)
    assert message.startswith(f'--address {http_server}: something listens there but it is not')
    assert 'ray start --head' in message and '\n' not in message
    assert time.monotonic() - started < 5.0  # the server answers at once: no waiting for Ray


def test_an_address_that_never_answers_or_refuses_is_one_line():
    with socket.socket() as silent:
        silent.bind(('127.0.0.1', 0))
        silent.listen()  # accepts, never answers
        address = f'127.0.0.1:{silent.getsockname()[1]}'
        with pytest.raises(EngineError, match='no gRPC answer in 0.5 s'):
            check_address(address, timeout=0.5)
    with pytest.raises(EngineError, match='no Ray head answers there'):
        check_address(address)  # closed now: refused
    with pytest.raises(EngineError, match='expected HOST:PORT'):
        check_address('localhost')


@pytest.mark.parametrize(('number', 'code'), [(signal.SIGINT, 130), (signal.SIGTERM, 143)])
def test_a_signal_during_a_tune_run_ends_it_through_tune_then_raises(number, code):
    """Tune's SIGUSR1 handler (here a stand-in) is asked to end the run; the run then raises
    Interrupted with the shell's exit code; the handlers are the old ones afterwards."""
    before = signal.getsignal(number)
    asked = []
    with sweep_stop.signals_stop() as mark:
        assert os.environ[sweep_stop.MARK] == mark
        assert os.environ['TUNE_DISABLE_SIGINT_HANDLER'] == '1'  # Tune leaves SIGINT to us
        with pytest.raises(sweep_stop.Interrupted) as stop, sweep_stop.tune_run():
            signal.signal(signal.SIGUSR1, lambda *_: asked.append('end the run'))  # as Tune
            os.kill(os.getpid(), number)
            time.sleep(0.1)  # Python runs the handler between bytecodes, here
            assert asked == ['end the run']  # the run went on to its end (Tune's)
        assert stop.value.exit_code == code and stop.value.name == signal.Signals(number).name
        with pytest.raises(sweep_stop.Interrupted):  # outside a Tune run: at once
            os.kill(os.getpid(), number)
            time.sleep(0.1)
    assert signal.getsignal(number) == before and sweep_stop.MARK not in os.environ


def test_a_signal_inside_a_ray_call_comes_out_as_interrupted_not_a_bare_keyboard_interrupt():
    """Ray raises a bare KeyboardInterrupt when a handler raised inside its blocking calls; the
    sweep's stop must keep its signal (its exit code)."""
    with sweep_stop.signals_stop():
        with pytest.raises(sweep_stop.Interrupted) as stop, sweep_stop.ray_calls():
            with contextlib.suppress(sweep_stop.Interrupted):  # what Ray drops
                os.kill(os.getpid(), signal.SIGTERM)
                time.sleep(0.1)
            raise KeyboardInterrupt  # what Ray raises instead
        assert stop.value.exit_code == 143
    with pytest.raises(KeyboardInterrupt) as plain, sweep_stop.ray_calls():
        raise KeyboardInterrupt  # no sweep stop asked: a KeyboardInterrupt stays one
    assert not isinstance(plain.value, sweep_stop.Interrupted)


def _records(trial_id: str, ok: bool, score: float = 0.9) -> list[dict]:
    return [{'trial': trial_id, 'status': 'ok' if ok else 'failed', 'score': score}]


def test_progress_lines_name_each_retried_trial_and_why_and_count_failures():
    lines = []
    progress = Progress(3, lines.append, 2, 'sweep', objective)  # no sweep stopped: no signal
    progress.started('a')
    progress.started('b')
    progress.retried('b', 'its node died', 2, 3)
    progress.started('b')
    progress.finished('a', _records('a', True, 0.8))
    progress.finished('b', _records('b', True, 0.9))
    progress.started('c')
    progress.finished('c', [])  # a trial that brought nothing back failed
    progress.finish()
    assert lines[2] == (
        'sweep: trial b lost its worker (its node died), retried from the start (attempt 2 of '
        '3): 0/3 done, 1 running, 0 failed, 1 retried, ETA after the first trial'
    )
    assert lines[5].startswith('sweep: trial finished: 2/3 done, 0 running, 0 failed, 1 retried, '
                               'best 0.900 (b), ETA ')  # fmt: skip
    assert lines[7].startswith('sweep: trial failed: 3/3 done, 0 running, 1 failed, 1 retried')
    assert lines[8].startswith('sweep: 3/3 trials done, 1 failed, 1 retried, in ')
    assert lines[9] == 'sweep: retried after a lost worker: b (its node died)'


def test_lost_trials_are_failed_records_per_seed_and_workers_build_each_scenario_once():
    trial = make_trial('gym', 'simple-maze', 'easy', 'dyna', [3, 4], 20, 10, 0.0, {})
    records = lost_records(trial, 'its node died (3 attempts)')
    assert [r['seed'] for r in records] == [3, 4]
    assert {r['status'] for r in records} == {'failed'}
    assert records[0]['error'] == 'worker lost: its node died (3 attempts)'
    assert records[0]['settings']['learner'] == 'dyna' and 'id' not in records[0]['settings']
    others = [make_trial('gym', 'simple-maze', 'easy', 'qlearning', [0], 20, 10, 0.0, {}),
              make_trial('ros', 'map1', None, 'dyna', [0], 20, 10, 0.0, {}),
              {'id': 'case', 'scenario': 'map1'}]  # fmt: skip
    assert scenarios_of([trial, *others]) == [('simple-maze', 'easy'), ('map1', None)]


def test_failed_runs_are_one_line_each_with_their_own_error(tmp_path):
    store = SweepStore(tmp_path)
    good = make_trial('gym', 'simple-maze', 'easy', 'dyna', [0], 20, 10, 0.0, {})
    bad = make_trial('ros', 'simple-maze', 'easy', 'dyna', [0], 20, 10, 0.1, {})
    store.add(lost_records(bad, 'ValueError: a ROS trial has no slip', prefix=''))
    store.add([{**lost_records(good, '')[0], 'status': 'ok', 'error': ''}])
    failed, runs = failed_runs(tmp_path)
    assert runs == 2
    assert failed == [f'{bad["id"]} seed 0: ValueError: a ROS trial has no slip']


def test_a_ros_trial_settles_on_the_criterion_column_not_the_return():
    """A ROS run's greedy returns can beat the optimum's (the goal reward follows the continuous
    pose) while its path does not meet the criterion: the criterion column decides."""
    eval_at = [10, 20, 30]
    rows = [
        {'total_reward': '1035.0', 'meets_criterion': 'False'},
        {'total_reward': '1035.0', 'meets_criterion': 'True'},
        {'total_reward': '1035.0', 'meets_criterion': 'True'},
    ]
    assert ros_settled(eval_at, rows, optimum=989.6) == 20
    old = [{'total_reward': r['total_reward']} for r in rows]  # an episodes.csv before scores
    assert ros_settled(eval_at, old, optimum=989.6) == 10
