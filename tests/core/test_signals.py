"""Stop signals deferred to safe points (:func:`camsim.core.signals.signals_deferred`): noted in the block, acted on
by ``act()`` or at its end as the handlers in force before it would have, dropped when the block already fails."""

import signal
import threading

import pytest

from camsim.core.signals import signals_deferred


@pytest.fixture(autouse=True)
def python_s_own_sigint_handler():
    """Python's own Ctrl-C handler (KeyboardInterrupt), whatever the test runner's process has set."""
    previous = signal.signal(signal.SIGINT, signal.default_int_handler)
    yield
    signal.signal(signal.SIGINT, previous)


def test_a_signal_in_the_block_waits_for_act():
    with signals_deferred() as deferred:
        signal.raise_signal(signal.SIGINT)  # Python's own handler would raise KeyboardInterrupt right here
        assert deferred.received == [signal.SIGINT]
        with pytest.raises(KeyboardInterrupt):
            deferred.act()
        assert deferred.received == []
        deferred.act()  # nothing left: nothing happens


def test_the_previous_handler_acts_and_comes_back():
    seen = []
    previous = signal.signal(signal.SIGTERM, lambda signum, frame: seen.append(signum))
    try:
        with signals_deferred() as deferred:
            signal.raise_signal(signal.SIGTERM)
            signal.raise_signal(signal.SIGTERM)
            assert seen == []
            deferred.act()
            assert seen == [signal.SIGTERM]  # the first acts, the others are dropped
        signal.raise_signal(signal.SIGTERM)
        assert seen == [signal.SIGTERM, signal.SIGTERM]  # the handler is back after the block
    finally:
        signal.signal(signal.SIGTERM, previous)


def test_a_signal_not_acted_on_acts_as_the_block_ends():
    with pytest.raises(KeyboardInterrupt):
        with signals_deferred():
            signal.raise_signal(signal.SIGINT)
    assert signal.getsignal(signal.SIGINT) is signal.default_int_handler


def test_a_block_that_fails_drops_what_it_noted():
    with pytest.raises(ValueError):
        with signals_deferred():
            signal.raise_signal(signal.SIGINT)
            raise ValueError("the work failed first")
    assert signal.getsignal(signal.SIGINT) is signal.default_int_handler


def test_outside_the_main_thread_nothing_is_deferred():
    got = []

    def run():
        with signals_deferred() as deferred:
            got.append((deferred.received, signal.getsignal(signal.SIGINT)))

    thread = threading.Thread(target=run)
    thread.start()
    thread.join()
    assert got == [([], signal.default_int_handler)]
