"""launch/demo.launch.py, checked without the launch packages (they have no wheels here).

The file is parsed with ``ast``: it may import only launch/launch_ros names that exist in
Jazzy (verified against ros2/launch and ros2/launch_ros, branch jazzy, where the file was
also run with ``launch.LaunchService``); its nodes name executables that setup.py declares;
the parameters it sets are ones those nodes declare; its launch arguments are the documented
ones.
"""

from __future__ import annotations

import ast
from pathlib import Path

import pytest

REPO = Path(__file__).resolve().parents[1]
LAUNCH_FILE = REPO / "launch" / "demo.launch.py"

# module -> names checked to exist in that module on the jazzy branches
JAZZY_NAMES = {
    "launch": {"LaunchDescription"},
    "launch.actions": {"DeclareLaunchArgument", "IncludeLaunchDescription", "GroupAction"},
    "launch.conditions": {"IfCondition", "UnlessCondition"},
    "launch.substitutions": {"LaunchConfiguration", "PathJoinSubstitution"},
    "launch_ros.actions": {"Node"},
    "launch_ros.parameter_descriptions": {"ParameterValue"},
    "launch_ros.substitutions": {"FindPackageShare"},
    "ament_index_python.packages": {"get_package_share_directory"},
}
NODE_KEYWORDS = {"package", "executable", "name", "namespace", "parameters", "remappings",
                 "arguments", "output", "condition", "ros_arguments"}
LAUNCH_ARGUMENTS = {"scene", "rate_hz", "algorithm", "frame", "record"}


def _tree() -> ast.Module:
    return ast.parse(LAUNCH_FILE.read_text(), filename=str(LAUNCH_FILE))


def _calls(tree, name):
    return [n for n in ast.walk(tree) if isinstance(n, ast.Call)
            and getattr(n.func, "id", getattr(n.func, "attr", None)) == name]


def _kw(call, key):
    for k in call.keywords:
        if k.arg == key:
            return k.value
    return None


def _setup_executables() -> set[str]:
    tree = ast.parse((REPO / "setup.py").read_text())
    for node in ast.walk(tree):
        if isinstance(node, ast.Assign) and getattr(node.targets[0], "id", "") == "EXECUTABLES":
            return set(ast.literal_eval(node.value))
    raise AssertionError("setup.py has no EXECUTABLES table")


def _node_specs(executable: str) -> set[str]:
    from gyro_attitude.ros import (
        attitude_integrator_node,
        gyro_sim_node,
        mcap_player_node,
        mcap_recorder_node,
    )

    module = {"gyro_sim": gyro_sim_node, "attitude_integrator": attitude_integrator_node,
              "mcap_recorder": mcap_recorder_node, "mcap_player": mcap_player_node}[executable]
    return {s.name for s in module.parameter_specs()}


def test_imports_only_jazzy_launch_api():
    tree = _tree()
    assert ast.literal_eval(next(n.value for n in tree.body if isinstance(n, ast.Assign)
                                 and n.targets[0].id == "PACKAGE")) == "gyro_attitude"
    for node in ast.walk(tree):
        if isinstance(node, ast.ImportFrom):
            allowed = JAZZY_NAMES.get(node.module)
            assert allowed is not None, f"imports from {node.module}"
            for alias in node.names:
                assert alias.name in allowed, f"{node.module}.{alias.name} is not verified"
        elif isinstance(node, ast.Import):
            assert all(a.name == "os" for a in node.names), [a.name for a in node.names]
    assert any(isinstance(n, ast.FunctionDef) and n.name == "generate_launch_description"
               for n in tree.body)


def test_launch_arguments_are_the_documented_ones():
    declared = {c.args[0].value for c in _calls(_tree(), "DeclareLaunchArgument")}
    assert declared == LAUNCH_ARGUMENTS
    used = {c.args[0].value for c in _calls(_tree(), "LaunchConfiguration")}
    assert used == LAUNCH_ARGUMENTS
    assert LAUNCH_ARGUMENTS <= set(
        (REPO / "README.md").read_text().split("demo.launch.py", 1)[1][:2000].replace(
            ":=", " ").replace("`", " ").split())


@pytest.mark.ros
def test_nodes_name_declared_executables_and_parameters():
    executables = _setup_executables()
    nodes = _calls(_tree(), "Node")
    started = set()
    for call in nodes:
        assert {k.arg for k in call.keywords} <= NODE_KEYWORDS
        assert getattr(_kw(call, "package"), "id", None) == "PACKAGE"
        exe = ast.literal_eval(_kw(call, "executable"))
        assert exe in executables, exe
        started.add(exe)
        declared = _node_specs(exe)
        params = _kw(call, "parameters")
        for item in params.elts:
            if isinstance(item, ast.Dict):
                names = {ast.literal_eval(k) for k in item.keys}
                assert names <= declared, (exe, names - declared)
            else:  # the installed config/<exe>.yaml
                assert any(isinstance(a, ast.Constant) and a.value == f"{exe}.yaml"
                           for a in ast.walk(item)), ast.dump(item)
    assert started == {"gyro_sim", "attitude_integrator", "mcap_recorder"}
    recorder = next(c for c in nodes if ast.literal_eval(_kw(c, "executable")) == "mcap_recorder")
    assert _kw(recorder, "condition") is not None  # only with record:=true
