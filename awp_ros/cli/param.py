"""
``awp_param``: list, get and set the parameters of a running node, without the ``ros2`` CLI.

::

    awp_param list /awp_node                       # every parameter name
    awp_param list /awp_node torque_limits         # those starting with torque_limits
    awp_param get /awp_node friction_coefficient stale_timeout_s
    awp_param set /awp_node friction_coefficient 0.5
    awp_param set /awp_node torque_limits.lf_kfe_joint '[-100, 120]'
    awp_param dump /awp_node                       # name: value, as YAML

What ``ros2 param list|get|set|dump`` do, through the same ``rcl_interfaces`` services of
the node (``<node>/list_parameters``, ``get_parameters``, ``set_parameters``), for pip users
whose venv has no ``ros2`` command. Values are YAML (``true``, ``0.5``, ``[0, 0, 1]``);
an integer given for a parameter whose value is a double (or an integer list for a double
list) is sent as that double, as the node would take it from a parameters file, and a
string parameter takes the text as typed (``awp_param set /awp_node robot_description
"$(cat robot.urdf)"``).
Several ``NAME VALUE`` pairs of one ``set`` are set one by one, in order. The DDS domain and
discovery range are those of the environment (``ROS_DOMAIN_ID``,
``ROS_AUTOMATIC_DISCOVERY_RANGE``).

Exit status: 0 done; 2 bad arguments, an unknown parameter or a value the node rejected
(its reason on stderr); 1 the node did not answer within ``--timeout``.
"""

from __future__ import annotations

import argparse
import sys

from rcl_interfaces.msg import ParameterType
from rcl_interfaces.srv import GetParameters, ListParameters, SetParameters
import rclpy
from rclpy.executors import SingleThreadedExecutor
from rclpy.parameter import Parameter, parameter_value_to_python
import yaml

from awp_ros.errors import ConfigError, ProcessError
from awp_ros.robot.parameters import close_matches

__all__ = ['main']

PROG = 'awp_param'


def _parser() -> argparse.ArgumentParser:
    p = argparse.ArgumentParser(
        prog=PROG, description='List, get and set the parameters of a running ROS 2 node '
        '(what ros2 param does), through its parameter services.')
    p.add_argument('--timeout', type=float, default=10.0,
                   help='seconds to wait for the node (default: %(default)s)')
    sub = p.add_subparsers(dest='command', required=True)
    c = sub.add_parser('list', help='print the parameter names (one per line)')
    c.add_argument('node', help='node name, e.g. /awp_node')
    c.add_argument('prefix', nargs='?', default='', help='only names starting with this')
    c = sub.add_parser('get', help='print parameter values (NAME: VALUE)')
    c.add_argument('node')
    c.add_argument('names', nargs='+', metavar='NAME')
    c = sub.add_parser('set', help='set parameters (NAME VALUE pairs, YAML values)')
    c.add_argument('node')
    c.add_argument('pairs', nargs='+', metavar='NAME VALUE')
    c = sub.add_parser('dump', help='print every parameter as YAML')
    c.add_argument('node')
    return p


def main(argv: list[str] | None = None) -> int:
    """Run ``awp_param``; return the exit status."""
    args = _parser().parse_args(argv)
    if args.command == 'set' and len(args.pairs) % 2:
        sys.stderr.write(f'{PROG}: error: set takes NAME VALUE pairs, got {args.pairs}\n')
        return 2
    context = rclpy.Context()
    rclpy.init(context=context)
    node = rclpy.create_node('awp_param', context=context,
                             start_parameter_services=False)
    try:
        return _run(node, args)
    except ConfigError as exc:
        sys.stderr.write(f'{PROG}: error: {exc}\n')
        return 2
    except ProcessError as exc:
        sys.stderr.write(f'{PROG}: error: {exc}\n')
        return 1
    finally:
        node.destroy_node()
        rclpy.try_shutdown(context=context)


def _run(node, args) -> int:
    target = args.node if args.node.startswith('/') else '/' + args.node
    target = target.rstrip('/')
    client = _Client(node, target, args.timeout)
    if args.command == 'list':
        for name in client.list_names(args.prefix):
            print(name)
        return 0
    if args.command in ('get', 'dump'):
        names = args.names if args.command == 'get' else client.list_names('')
        values = client.values(names)
        if args.command == 'dump':
            print(yaml.safe_dump({target: {'ros__parameters': values}}, sort_keys=False),
                  end='')
        else:
            for name in names:
                print(f'{name}: {yaml.safe_dump(values[name], default_flow_style=True).strip()}'
                      .replace('\n...', ''))
        return 0
    pairs = list(zip(args.pairs[::2], args.pairs[1::2]))
    current = client.values([name for name, _ in pairs])
    for name, text in pairs:
        value = _coerce(_yaml(text), current[name], text)
        client.set_value(name, value)
        print(f'set {name} = {value!r}')
    return 0


def _yaml(text: str):
    """Return a command-line value read as YAML (plain text when it is not YAML)."""
    try:
        return yaml.safe_load(text)
    except yaml.YAMLError:
        return text


def _coerce(value, current, text: str):
    """
    Return ``value`` in the parameter's current type where that is what the user meant.

    A double (list) parameter given an integer (list) gets the double (list); a string
    parameter gets the text as typed (``robot_description "$(cat robot.urdf)"``).
    """
    if isinstance(current, str):
        return text
    if isinstance(current, float) and isinstance(value, int) and not isinstance(value, bool):
        return float(value)
    if isinstance(current, list) and current and all(isinstance(x, float) for x in current) \
            and isinstance(value, list) and all(isinstance(x, int) and not isinstance(x, bool)
                                                for x in value):
        return [float(x) for x in value]
    return value


class _Client:
    """The parameter services of one node."""

    def __init__(self, node, target: str, timeout_s: float) -> None:
        self.node = node
        self.executor = SingleThreadedExecutor(context=node.context)
        self.executor.add_node(node)
        self.target = target
        self.timeout_s = timeout_s
        self.list_ = node.create_client(ListParameters, f'{target}/list_parameters')
        self.get_ = node.create_client(GetParameters, f'{target}/get_parameters')
        self.set_ = node.create_client(SetParameters, f'{target}/set_parameters')

    def _call(self, client, request):
        if not client.wait_for_service(timeout_sec=self.timeout_s):
            raise ProcessError(f'node {self.target!r} did not answer on {client.srv_name} '
                               f'within {self.timeout_s:g} s (is it running, on this '
                               'ROS_DOMAIN_ID?)')
        future = client.call_async(request)
        self.executor.spin_until_future_complete(future, timeout_sec=self.timeout_s)
        if not future.done() or future.result() is None:
            raise ProcessError(f'node {self.target!r} did not answer {client.srv_name} '
                               f'within {self.timeout_s:g} s')
        return future.result()

    def list_names(self, prefix: str) -> list[str]:
        """Return the node's parameter names (starting with ``prefix``), sorted."""
        result = self._call(self.list_, ListParameters.Request()).result
        return sorted(n for n in result.names if n.startswith(prefix))

    def values(self, names: list[str]) -> dict:
        """
        Return ``{name: value}``; ConfigError for names the node does not have.

        A node answers nothing at all for a request naming an undeclared parameter (rclpy),
        so the names are checked against its list first.
        """
        known = self.list_names('')
        unknown = [n for n in names if n not in known]
        if unknown:
            raise ConfigError(f'node {self.target!r} has no parameter '
                              + ', '.join(f'{n!r}{close_matches(n, known)}' for n in unknown))
        result = self._call(self.get_, GetParameters.Request(names=list(names)))
        values = {}
        for name, value in zip(names, result.values):
            if value.type == ParameterType.PARAMETER_NOT_SET:
                unknown.append(name)
                continue
            v = parameter_value_to_python(value)
            values[name] = list(v) if isinstance(v, (list, tuple)) or hasattr(v, 'tolist') \
                else v
        if unknown:
            raise ConfigError(f'node {self.target!r} has parameters {unknown} but no value '
                              'for them (declared, not set)')
        return values

    def set_value(self, name: str, value) -> None:
        """Set one parameter; ConfigError with the node's reason when it is rejected."""
        try:
            msg = Parameter(name, value=value).to_parameter_msg()
        except (TypeError, ValueError) as exc:
            raise ConfigError(f'{name}: cannot send {value!r} as a parameter: {exc}') from exc
        result = self._call(self.set_, SetParameters.Request(parameters=[msg])).results[0]
        if not result.successful:
            raise ConfigError(f'{self.target} rejected {name} = {value!r}: {result.reason}')


if __name__ == '__main__':
    sys.exit(main())
