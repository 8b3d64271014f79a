"""Input subscriptions taken on a thread of their own instead of by rclpy's executor.

rclpy's executors (Jazzy) rebuild a wait set of every entity of the node (subscriptions,
timers, the parameter services, guard conditions) on every wake-up and dispatch one callback
per message through Python generators: far more CPU per message than integrating the sample
(``bench --suite nodes`` profiles the integrator). :class:`InputThread` waits on its own small
wait set holding only the input subscriptions and a guard condition that wakes it to stop, and
takes every queued message of a ready subscription in one go, on one thread: the order of the
input callbacks among themselves is the order in which this thread takes them, and the
executor, left with the timers and services, runs on the main thread.

A subscription created with ``callback_group=thread.group`` is never put in an executor's wait
set (:class:`_TakenByThread`), nor are its QoS event handlers (incompatible QoS, message lost):
this thread waits on them too and calls their callbacks (rclpy's default ones log). Left in
the executor's wait set, they woke it at every message of the subscription (with the pinned
Fast DDS rmw), and the executor then rebuilt its wait set for nothing: ~28 % of a core at
4 kHz. ``lock`` is held while a batch of messages is handled: callbacks of the executor
(timers, parameter changes) that touch the same state take it too.
"""

from __future__ import annotations

import threading
from collections.abc import Callable
from contextlib import ExitStack

from rclpy.callback_groups import CallbackGroup
from rclpy.guard_condition import GuardCondition
from rclpy.impl.implementation_singleton import rclpy_implementation as _rclpy
from rclpy.subscription import Subscription

__all__ = ["InputThread"]


class _TakenByThread(CallbackGroup):
    """The callback group of the subscriptions (and their QoS event handlers) an
    :class:`InputThread` takes: an executor never waits on them."""

    def can_execute(self, entity) -> bool:
        return False

    def beginning_execution(self, entity) -> bool:
        return False

    def ending_execution(self, entity) -> None:
        pass


class InputThread:
    """Waits on ``add``-ed subscriptions and hands their messages to their handlers.

    ``batch``: at most this many messages of one subscription per turn, so a fast topic
    cannot hold back a slow one (all subscriptions are visited in the order they were added,
    every turn) nor hold ``lock`` for long.  ``wait_s``: the longest wait before the stop flag
    and the context are checked again (a stop also wakes the wait at once).
    """

    def __init__(self, context, lock: threading.Lock, *, batch: int = 64,
                 wait_s: float = 0.2, name: str = "inputs"):
        self.group = _TakenByThread()
        self._context = context
        self._lock = lock
        self._batch = batch
        self._wait_ns = int(wait_s * 1e9)
        self._name = name
        self._entries: list[tuple[Subscription, Callable, bool]] = []
        self._stop = threading.Event()
        self._wake: GuardCondition | None = None
        self._thread: threading.Thread | None = None
        self.failure: BaseException | None = None  # what ended the thread, if not a stop

    def add(self, subscription: Subscription, handler: Callable, *,
            with_info: bool = False) -> None:
        """Take ``subscription``'s messages (created with ``callback_group=self.group``) and
        call ``handler(message)`` for each, in the order of arrival
        (``handler(message, info)`` with ``with_info``: rclpy's message info, a dict with the
        middleware's ``source_timestamp`` and ``received_timestamp``)."""
        if self._thread is not None:
            raise RuntimeError("subscriptions are added before the thread starts")
        self._entries.append((subscription, handler, with_info))

    @property
    def running(self) -> bool:
        return self._thread is not None and self._thread.is_alive()

    def start(self) -> None:
        """Start taking messages (once; later calls do nothing)."""
        if self._thread is not None:
            return
        self._wake = GuardCondition(None, None, context=self._context)
        self._thread = threading.Thread(target=self._run, name=self._name, daemon=True)
        self._thread.start()

    def stop(self, timeout_s: float = 10.0) -> bool:
        """Ask the thread to stop, wake it and join it; False if it is still running after
        ``timeout_s`` (a handler that does not return)."""
        self._stop.set()
        if self._thread is None:
            return True
        try:
            self._wake.trigger()
        except Exception:  # the context is already shut down: the wait times out
            pass
        self._thread.join(timeout_s)
        if self._thread.is_alive():
            return False
        try:
            self._wake.destroy()
        except Exception:
            pass
        return True

    def _run(self) -> None:
        try:
            with ExitStack() as held:
                # the handles stay entered while the thread may use them: a subscription or
                # the context cannot be destroyed under it (destruction waits for the exit)
                events = [e for sub, _, _ in self._entries for e in sub.event_handlers]
                for sub, _, _ in self._entries:
                    held.enter_context(sub.handle)
                for event in events:
                    held.enter_context(event)
                held.enter_context(self._wake.handle)
                held.enter_context(self._context.handle)
                n_events = sum(e.get_num_entities().num_events for e in events)
                wait_set = _rclpy.WaitSet(len(self._entries), 1, 0, 0, 0, n_events,
                                          self._context.handle)
                while not self._stop.is_set():
                    wait_set.clear_entities()
                    for sub, _, _ in self._entries:
                        wait_set.add_subscription(sub.handle)
                    for event in events:
                        event.add_to_wait_set(wait_set)
                    wait_set.add_guard_condition(self._wake.handle)
                    wait_set.wait(self._wait_ns)  # releases the GIL while it waits
                    if self._stop.is_set() or not self._context.ok():
                        return
                    for event in events:
                        if event.is_ready(wait_set):
                            taken = event.take_data()
                            if taken:
                                with self._lock:
                                    event.callback(taken)
                    self._take_all()
        except BaseException as exc:  # SystemExit from a handler ends the node too
            if not (self._stop.is_set() or not self._context.ok()):
                self.failure = exc  # not a shutdown: the owner reports it

    def _take_all(self) -> None:
        """Every queued message, ``batch`` per subscription per turn, until none is left."""
        more = True
        while more and not self._stop.is_set():
            more = False
            with self._lock:
                for sub, handler, with_info in self._entries:
                    handle, msg_type, raw = sub.handle, sub.msg_type, sub.raw
                    for _ in range(self._batch):
                        taken = handle.take_message(msg_type, raw)
                        if taken is None:
                            break
                        if with_info:
                            handler(*taken)
                        else:
                            handler(taken[0])
                    else:
                        more = True


def spin_with_inputs(node, executor) -> None:
    """A ``spin`` for :func:`gyro_attitude.ros.node_main.run_node`: the node's ``inputs``
    thread (None: none) runs while the executor spins; the spin ends when the context is shut
    down or the thread ends, and the thread is stopped and joined before this returns. What
    ended the thread, other than a stop, is raised here, as an exception in an executor's
    callback would be."""
    inputs = getattr(node, "inputs", None)
    if inputs is None:
        executor.spin()
        return
    inputs.start()  # (a node may have started it already)
    try:
        while node.context.ok() and inputs.running:
            executor.spin_once(timeout_sec=0.2)
    finally:
        inputs.stop()
    if inputs.failure is not None:
        raise inputs.failure
