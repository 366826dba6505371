"""Packaging: package.xml, setup.cfg, ament index resolution as `ros2 run` does it,
launch file and config YAMLs."""
import ast
import os
import re
import xml.etree.ElementTree as ET
from pathlib import Path

import pytest
import yaml

ROOT = Path(__file__).resolve().parents[1]
EXECUTABLES = ('alignment_node', 'alignment_lifecycle_node', 'simulator_node')
#: console scripts of sins_align_ros/cli (no ROS graph): name -> module:function
TOOLS = {'sins_align_replay': 'replay:run', 'sins_align_record': 'record:main'}


def test_package_xml_is_format3_ament_python_with_rosdep_keys():
    root = ET.parse(ROOT / 'package.xml').getroot()
    assert root.get('format') == '3'
    assert root.findtext('name') == 'sins_align_ros'
    deps = {e.text for e in root if e.tag.endswith('depend')}
    for key in ('rclpy', 'sensor_msgs', 'geometry_msgs', 'nav_msgs', 'diagnostic_msgs',
                'std_srvs', 'python3-numpy', 'python3-scipy', 'python3-pytest'):
        assert key in deps, key
    assert root.find('export/build_type').text == 'ament_python'
    catkin_pkg = pytest.importorskip('catkin_pkg.package')
    pkg = catkin_pkg.parse_package(str(ROOT / 'package.xml'))
    pkg.validate()


def test_setup_cfg_installs_scripts_where_ros2_run_looks():
    text = (ROOT / 'setup.cfg').read_text()
    assert 'script_dir=$base/lib/sins_align_ros' in text
    assert 'install_scripts=$base/lib/sins_align_ros' in text
    setup = (ROOT / 'setup.py').read_text()
    for exe in EXECUTABLES:
        assert re.search(rf"'{exe} = sins_align_ros\.ros\.{exe}:main'", setup)
    for tool, target in TOOLS.items():
        assert f"'{tool} = sins_align_ros.cli.{target}'" in setup, tool


def resolve_executable(name):
    """Find ``name`` exactly as ``ros2 run sins_align_ros NAME`` does (ros2run.api).

    ros2run takes the package prefix from the ament index, then looks for an
    executable file of that name in ``<prefix>/lib/<package>``.
    """
    if not os.environ.get('AMENT_PREFIX_PATH'):
        pytest.skip('AMENT_PREFIX_PATH not set: run the README test command '
                    '(it builds with colcon and sources install/setup.bash)')
    from ament_index_python.packages import get_package_prefix
    prefix = get_package_prefix('sins_align_ros')
    path = os.path.join(prefix, 'lib', 'sins_align_ros', name)
    assert os.path.isfile(path) and os.access(path, os.X_OK), path
    return path


@pytest.mark.parametrize('exe', EXECUTABLES + tuple(TOOLS))
def test_executables_resolve_through_ament_index(exe):
    path = resolve_executable(exe)
    assert Path(path).parent.name == 'sins_align_ros'
    assert Path(path).parent.parent.name == 'lib'


def _launch_nodes(path):
    """(package, executable) of every Node(...) call in a launch file, by parsing it."""
    out = []
    for node in ast.walk(ast.parse(path.read_text())):
        if isinstance(node, ast.Call) and getattr(node.func, 'id', None) == 'Node':
            kw = {k.arg: k.value.value for k in node.keywords
                  if isinstance(k.value, ast.Constant)}
            out.append((kw.get('package'), kw.get('executable')))
    return out


def test_launch_files_name_real_executables():
    files = sorted((ROOT / 'launch').glob('*.launch.py'))
    assert files
    for f in files:
        nodes = _launch_nodes(f)
        assert nodes, f
        for pkg, exe in nodes:
            assert pkg == 'sins_align_ros'
            assert exe in EXECUTABLES
            if os.environ.get('AMENT_PREFIX_PATH'):
                resolve_executable(exe)


def test_launch_file_runs_where_launch_is_available():
    pytest.importorskip('launch', reason='launch/launch_ros not installed (PyPI ROS wheels '
                                         'do not ship them); parsed statically above')
    pytest.importorskip('launch_ros')
    import importlib.util
    f = ROOT / 'launch' / 'alignment.launch.py'
    spec = importlib.util.spec_from_file_location('alignment_launch', f)
    mod = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(mod)
    assert mod.generate_launch_description().entities


def _node_params(node_name):
    if node_name == 'alignment_node':
        from sins_align_ros.ros.alignment_node import PARAMS
    else:
        from sins_align_ros.ros.simulator_node import PARAMS
    return {p.name: p for p in PARAMS}


@pytest.mark.parametrize('path', sorted((ROOT / 'config').glob('*.yaml')), ids=lambda p: p.name)
def test_every_config_yaml_loads_and_is_valid(path):
    pytest.importorskip('rclpy')
    data = yaml.safe_load(path.read_text())
    assert data, path
    for node_name, body in data.items():
        assert node_name in EXECUTABLES, node_name
        params = _node_params(node_name)
        values = body['ros__parameters']
        for name, value in values.items():
            assert name in params, f'{path.name}: unknown parameter {name}'
            p = params[name]
            if p.is_array:          # a YAML list: rclpy declares a double array from it
                assert isinstance(value, list) and all(type(v) is float for v in value), name
            else:
                assert type(value) is type(p.default), (
                    f'{name}: {type(value)} != {type(p.default)}')
            assert p.check(value) is None, p.check(value)
