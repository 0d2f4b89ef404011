"""The serial driver nodes as managed (lifecycle) nodes, as ROS 2 users know them from other
drivers (REP-2002 style; ``lifecycle_msgs`` services ``~/change_state``, ``~/get_state``, ...).

- configure: the serial link starts; the port is opened and the device set up on the link's
  thread. A port that is not there yet is retried as a reconnect is (the driver finds a device
  plugged in later), so configure does not fail for it; /diagnostics says "port closed".
- activate: the measurements are published.
- deactivate: they are no longer published; the port stays open and the device streaming, so
  the timing models stay locked. What is read meanwhile is counted (``held_while_inactive``),
  never published late.
- cleanup, shutdown, error: the link stops and the port is closed (the device's stream stopped
  where the driver knows how).

``autostart`` (default true) runs configure and activate at start: a plain ``ros2 run`` or
``gnss_ins launch`` works as before. With ``autostart:=false`` the node waits, unconfigured, for a
lifecycle manager (nav2's lifecycle_manager, ``ros2 lifecycle set``, launch_ros LifecycleNode).
/diagnostics is published in every state.
"""

from __future__ import annotations

from collections.abc import Callable
from typing import Any

from rclpy.lifecycle import LifecycleNode, LifecycleState, TransitionCallbackReturn

from gnss_ins_common import ros_diagnostics as diag
from gnss_ins_common.params import AUTOSTART
from gnss_ins_common.serial_link import LinkStats, SerialLink

__all__ = ["AUTOSTART", "ManagedSerialDriver"]

_SUCCESS, _FAILURE = TransitionCallbackReturn.SUCCESS, TransitionCallbackReturn.FAILURE


class ManagedSerialDriver(LifecycleNode):
    """A driver node whose serial link follows the lifecycle (module docstring). A subclass
    gives ``open_link`` and may give ``stop_link``'s ``before_close``; its data path publishes
    only ``if self.publishing()``."""

    def __init__(self, node_name: str, **kwargs: Any) -> None:
        """A node in the unconfigured state, without a link."""
        super().__init__(node_name, **kwargs)
        self.link: SerialLink | None = None
        self.held_while_inactive = 0
        self._active = False
        self._last_stats = LinkStats()
        self._before_close: Callable[[Any], None] | None = None

    # ---- for the subclass ---------------------------------------------------------------------
    def open_link(self) -> SerialLink:
        """The started serial link of the driver (configure)."""
        raise NotImplementedError

    def start_managed(self, autostart: bool, before_close: Callable[[Any], None] | None) -> None:
        """End of the subclass's constructor: configure and activate when ``autostart``.
        ``before_close(port)``: what to send the device before its port is closed."""
        self._before_close = before_close
        if autostart:
            if self.trigger_configure() == _SUCCESS:
                self.trigger_activate()
        else:
            self.get_logger().info("unconfigured: waiting for the configure transition")

    def publishing(self, held: int = 1) -> bool:
        """True when active; else ``held`` more messages are counted as held while inactive."""
        if self._active:
            return True
        self.held_while_inactive += held
        return False

    @property
    def link_stats(self) -> LinkStats:
        """Counters of the link, or of the last one after cleanup."""
        return self.link.stats if self.link is not None else self._last_stats

    @property
    def port_open(self) -> bool:
        """True while the port is open and the device set up."""
        return self.link is not None and self.link.is_open

    def lifecycle_problem(self) -> tuple[bytes, str] | None:
        """Diagnostics level and message of a node that is not active, None when active."""
        if self._active:
            return None
        if self.link is None:
            return diag.WARN, "unconfigured (lifecycle): port closed, nothing published"
        return diag.WARN, "inactive (lifecycle): reading the device, nothing published"

    def close(self) -> None:
        """Stop the link (the node's end)."""
        self._active = False
        self._stop_link()

    # ---- transitions --------------------------------------------------------------------------
    def on_configure(self, state: LifecycleState) -> TransitionCallbackReturn:
        """Start the link (the port opened on its thread, retried until it is there)."""
        try:
            self.link = self.open_link()
        except Exception as exc:  # rclpy would turn it into ERROR without a word
            self.get_logger().error(f"configure failed: {exc}")
            return _FAILURE
        return _SUCCESS

    def on_activate(self, state: LifecycleState) -> TransitionCallbackReturn:
        """Publish from now on."""
        self._active = True
        self.get_logger().info("active: publishing")
        return super().on_activate(state)

    def on_deactivate(self, state: LifecycleState) -> TransitionCallbackReturn:
        """Stop publishing; the port stays open."""
        self._active = False
        self.get_logger().info("inactive: reading the device, not publishing")
        return super().on_deactivate(state)

    def on_cleanup(self, state: LifecycleState) -> TransitionCallbackReturn:
        """Stop the link and close the port."""
        self._stop_link()
        return _SUCCESS

    def on_shutdown(self, state: LifecycleState) -> TransitionCallbackReturn:
        """Stop publishing and the link."""
        self.close()
        return _SUCCESS

    def on_error(self, state: LifecycleState) -> TransitionCallbackReturn:
        """Back to unconfigured with the link stopped."""
        self.close()
        return _SUCCESS

    def _stop_link(self) -> None:
        """Stop the link (its thread may still deliver data until then), keep its counters."""
        link = self.link
        if link is not None:
            link.stop(before_close=self._before_close)
            self._last_stats, self.link = link.stats, None
