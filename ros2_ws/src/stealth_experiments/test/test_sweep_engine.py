"""The sweep driver's guards, without Ray: an --address that is not a Ray head is refused at
once, and SIGINT or SIGTERM become Interrupted (exit 130 or 143) after Tune's run returns."""

import http.server
import os
import signal
import socket
import threading
import time

import pytest
from stealth_experiments import sweep_stop
from stealth_experiments.sweep_engine import EngineError, check_address


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
