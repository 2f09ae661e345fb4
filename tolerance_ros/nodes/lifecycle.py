"""Managed (lifecycle) versions of the suite's nodes, ``rclpy.lifecycle``: ``managed(cls)`` is the node class
``cls`` (any node of the suite: a ``NODE_NAME`` and a ``setup()`` that declares, loads and subscribes)
driven by the lifecycle state machine instead of starting at once.

- configure: ``setup()`` runs: parameters, robots, compiled kernels, files, publishers, subscriptions and
  timers are made (the timers cancelled); nothing is served yet; a package the node needs that is missing
  fails the transition, naming it (``services.dependencies``);
- activate: callbacks take effect and the timers are reset (they start counting their period): the node serves;
- deactivate: callbacks stop taking effect (messages are ignored) and the timers are cancelled, so that an
  inactive node does not wake the executor; the state, budgets, logs and statistics are kept, and activate
  resumes where it stopped;
- cleanup / shutdown: what setup made is destroyed (``close()`` first), and configure may run again.

Plain nodes stay the default; ``ros2 run tolerance_ros <node> --managed`` (or ``managed:=true`` in the
launch files) runs the managed one, driven by ``ros2 lifecycle set <node> configure`` and so on.
"""
from __future__ import annotations

from rclpy.lifecycle import LifecycleNodeMixin, TransitionCallbackReturn
from rclpy.node import Node


def managed(cls):
    """The lifecycle-managed version of node class ``cls`` (see the module docstring)."""

    class Managed(LifecycleNodeMixin, cls):
        def __init__(self, **node_options):
            self._active = False
            self._made = None            # what setup() made, while it runs and after
            Node.__init__(self, cls.NODE_NAME, **node_options)
            LifecycleNodeMixin.__init__(self)

        def _gate(self, callback):
            def gated(*args):
                if self._active:
                    return callback(*args)
                return None
            gated.__name__ = getattr(callback, "__name__", "callback")
            return gated

        def create_subscription(self, msg_type, topic, callback, qos_profile, **kwargs):
            if self._made is None:
                return super().create_subscription(msg_type, topic, callback, qos_profile, **kwargs)
            sub = super().create_subscription(msg_type, topic, self._gate(callback), qos_profile, **kwargs)
            self._made.append(("subscription", sub))
            return sub

        def create_timer(self, timer_period_sec, callback, *args, **kwargs):
            if self._made is None:
                return super().create_timer(timer_period_sec, callback, *args, **kwargs)
            timer = super().create_timer(timer_period_sec, self._gate(callback), *args, **kwargs)
            self._made.append(("timer", timer))
            return timer

        def create_publisher(self, *args, **kwargs):
            pub = super().create_publisher(*args, **kwargs)
            if self._made is not None:
                self._made.append(("publisher", pub))
            return pub

        def on_configure(self, state):
            self._made = []
            try:
                self.setup()
            except Exception as exc:  # a bad parameter or file: the transition fails, the node stays unconfigured
                self.get_logger().error(f"configure failed: {type(exc).__name__}: {exc}")
                self._destroy()
                return TransitionCallbackReturn.FAILURE
            self._timers_on(False)
            self.get_logger().info("configured: robots, kernels and files loaded; activate to serve")
            return TransitionCallbackReturn.SUCCESS

        def on_activate(self, state):
            self._active = True
            self._timers_on(True)
            self.get_logger().info("active: serving")
            return super().on_activate(state)

        def on_deactivate(self, state):
            self._active = False
            self._timers_on(False)
            self.get_logger().info("inactive: not serving, timers cancelled, state kept")
            return super().on_deactivate(state)

        def made_timers(self) -> list:
            """The timers setup() made (cancelled while the node is not active)."""
            return [entity for kind, entity in self._made or [] if kind == "timer"]

        def _timers_on(self, on: bool):
            for timer in self.made_timers():
                timer.reset() if on else timer.cancel()

        def on_cleanup(self, state):
            self._destroy()
            return TransitionCallbackReturn.SUCCESS

        def on_shutdown(self, state):
            self._destroy()
            return TransitionCallbackReturn.SUCCESS

        def _destroy(self):
            self._active = False
            close = getattr(self, "close", None)
            if close is not None and self._made:
                close()
            for kind, entity in reversed(self._made or []):
                {"subscription": self.destroy_subscription, "timer": self.destroy_timer,
                 "publisher": self.destroy_publisher}[kind](entity)
            self._made = None

        def close(self):
            if self._made is not None:
                parent = getattr(cls, "close", None)
                if parent is not None:
                    parent(self)

    Managed.__name__ = Managed.__qualname__ = f"Managed{cls.__name__}"
    return Managed
