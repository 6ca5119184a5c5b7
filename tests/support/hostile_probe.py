"""A peer on the ROS domain that pokes a node running as its own process, as a hostile one would.

It sets parameters through the node's real `set_parameters` service (what `ros2 param set`
does), publishes arbitrary messages, reads /diagnostics, and tells whether the process is
still alive and answering. Used by tests/hostile/.
"""

from __future__ import annotations

from typing import Any

from ros_fixtures import RosProcess
from ros_waiting import wait_until

TIMEOUT = 30.0  # [s] generous: DDS discovery alone can take about 2 s


class HostileProbe:
    """A probe node beside `process` (the node `node_name` under test).

    Probes of several processes can share one `executor`, so that waiting on one spins all.
    """

    def __init__(self, context: Any, process: RosProcess, node_name: str,
                 executor: Any = None) -> None:
        import rclpy
        from diagnostic_msgs.msg import DiagnosticArray
        from rcl_interfaces.srv import GetParameters, SetParameters
        from rclpy.executors import SingleThreadedExecutor
        from stereo_fuzzy_perception.nodes import qos

        self.process, self.node_name = process, node_name
        self.node = rclpy.create_node(f'hostile_probe_{node_name}', context=context)
        self._own_executor = executor is None
        self.executor = SingleThreadedExecutor(context=context) if executor is None else executor
        self.executor.add_node(self.node)
        self._set = self.node.create_client(SetParameters, f'/{node_name}/set_parameters')
        self._get = self.node.create_client(GetParameters, f'/{node_name}/get_parameters')
        self.diagnostics: dict[str, dict[str, str]] = {}
        self.node.create_subscription(DiagnosticArray, '/diagnostics', self._on_diagnostics,
                                      qos.DIAGNOSTICS)
        self.wait(lambda: self._set.service_is_ready() and self._get.service_is_ready(),
                  f'the parameter services of {node_name}')

    def _on_diagnostics(self, array: Any) -> None:
        for status in array.status:
            if status.name.startswith(f'{self.node_name}:'):
                values = {item.key: item.value for item in status.values}
                values['message'] = status.message
                self.diagnostics[status.name] = values

    def wait(self, predicate: Any, what: str, timeout: float = TIMEOUT) -> None:
        """Spin until `predicate()` holds; fail naming `what` (and the node's log if it died)."""
        def holds() -> bool:
            if self.process.process.poll() is not None:
                raise AssertionError(f'{self.node_name} died (exit {self.process.process.poll()}) '
                                     f'while waiting for {what}:\n{self.process.output()[-3000:]}')
            return bool(predicate())
        wait_until(holds, timeout, what, self.executor)

    def call(self, client: Any, request: Any, what: str) -> Any:
        """Call a service and return its response (fails if the node stops answering)."""
        future = client.call_async(request)
        self.wait(future.done, f'{self.node_name} to answer {what}')
        return future.result()

    def set_parameter(self, name: str, value: Any) -> tuple[bool, str]:
        """Set one parameter through the service; return (successful, reason)."""
        from rclpy.parameter import Parameter

        message = Parameter(name, value=value).to_parameter_msg()
        return self.set_parameter_message(message)

    def set_parameter_message(self, message: Any) -> tuple[bool, str]:
        """Send one rcl_interfaces/Parameter message as it is; return (successful, reason)."""
        from rcl_interfaces.srv import SetParameters

        response = self.call(self._set, SetParameters.Request(parameters=[message]),
                             f'set_parameters {message.name}')
        result = response.results[0]
        return bool(result.successful), str(result.reason)

    def get_parameter(self, name: str) -> Any:
        """Return the current value of a parameter (through the get_parameters service)."""
        from rcl_interfaces.srv import GetParameters
        from rclpy.parameter import parameter_value_to_python

        response = self.call(self._get, GetParameters.Request(names=[name]),
                             f'get_parameters {name}')
        return parameter_value_to_python(response.values[0])

    def assert_alive(self) -> None:
        """Fail unless the process runs and still answers a parameter request."""
        assert self.process.process.poll() is None, (
            f'{self.node_name} died:\n{self.process.output()[-3000:]}')
        self.get_parameter('use_sim_time')

    def counter(self, key: str) -> int:
        """Return the latest /diagnostics count of `key` from the node (0 before any)."""
        value = self.diagnostic_value(key)
        return int(value) if value is not None else 0

    def diagnostic_value(self, key: str) -> str | None:
        """Return the latest /diagnostics value of `key` from the node, or None."""
        for values in self.diagnostics.values():
            if key in values:
                return values[key]
        return None

    def wait_diagnostic(self, key: str, expected: Any, what: str = '') -> None:
        """Wait until the node reports `key` = str(expected) on /diagnostics."""
        self.wait(lambda: self.diagnostic_value(key) == str(expected),
                  what or f'/diagnostics {key!r} = {expected} (last: '
                  f'{self.diagnostic_value(key)!r})')

    def close(self) -> None:
        """Destroy the probe node (and its executor, unless shared)."""
        if self._own_executor:
            self.executor.shutdown()
        else:
            self.executor.remove_node(self.node)
        self.node.destroy_node()
