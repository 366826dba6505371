"""The engine contract (align/engines/base.py) is what the stages use, and every engine keeps it.

Every engine :func:`make_engine` builds (each ``fine_filter`` of ``FINE_FILTERS``) satisfies
:class:`Engine` and the protocol of its kind; and the protocols declare exactly the engine
members ``align/stages`` and ``align/pipeline.py`` read, found by an AST scan of their
source: a stage that starts using an undeclared member (or reaches into the engine's
filter) fails here, and so does a declared member no stage uses any more.
"""
import ast
import math
from pathlib import Path

import numpy as np
import pytest

from sins_align_ros.align import params as prm
from sins_align_ros.align.engines.base import AidedEngine, Engine, StillEngine
from sins_align_ros.align.engines.factory import make_engine, noise_spec
from sins_align_ros.align.stages.coarse_stage import CoarseResult
from sins_align_ros.align.stages.motion_check import TRIADS

ALIGN = Path(__file__).resolve().parents[1] / 'sins_align_ros' / 'align'
#: the sources whose engine reads the contract declares
SCANNED = sorted((ALIGN / 'stages').glob('*.py')) + [ALIGN / 'pipeline.py']
#: names an engine goes by in those sources (``self.engine``, ``stage.engine``: any ``.engine``)
ENGINE_NAMES = {'engine', 'eng'}
PROTOCOLS = (Engine, StillEngine, AidedEngine)
#: members a stage calls by a name it holds as data (the motion check's setter per triad)
BY_NAME = {triad[2] for triad in TRIADS}


def declared(proto):
    """Return the member names a protocol declares (its own and its protocol bases')."""
    names = set()
    for cls in proto.__mro__:
        if getattr(cls, '_is_protocol', False) and cls.__module__ == Engine.__module__:
            names |= set(cls.__dict__.get('__annotations__', {}))
            names |= {k for k in vars(cls) if not k.startswith('_')}
    return names


def _is_engine(node):
    """Tell whether an expression names an engine: ``engine``, ``eng`` or ``<x>.engine``."""
    return ((isinstance(node, ast.Name) and node.id in ENGINE_NAMES)
            or (isinstance(node, ast.Attribute) and node.attr == 'engine'))


def engine_reads(source):
    """Return the engine members a module's ``source`` reads, calls or sets.

    ``engine.X``, ``eng.X``, ``<x>.engine.X``, and ``getattr``/``hasattr``/``setattr`` of
    such an engine with a constant name.
    """
    found = set()
    for node in ast.walk(ast.parse(source)):
        if isinstance(node, ast.Attribute) and _is_engine(node.value):
            found.add(node.attr)
        elif (isinstance(node, ast.Call) and isinstance(node.func, ast.Name)
              and node.func.id in ('getattr', 'hasattr', 'setattr') and len(node.args) >= 2
              and _is_engine(node.args[0]) and isinstance(node.args[1], ast.Constant)):
            found.add(node.args[1].value)
    return found


def _start():
    """A coarse result at 45 deg N: level, heading north, 1 deg tilt and 5 deg heading sigma."""
    return CoarseResult(np.eye(3), np.radians([1.0, 1.0, 5.0]),
                        np.array([math.radians(45.0), math.radians(7.0), 100.0]))


def test_the_scanner_sees_a_reach_into_the_filter():
    """The scan finds reads through every engine name, getattr included (so the test can fail)."""
    src = ('def f(self, eng, engine):\n'
           '    self.engine.kf.P\n'
           '    eng.mech.C_b_n\n'
           '    getattr(engine, "heading_lost", False)\n'
           '    self.fine.engine.status()\n')
    assert engine_reads(src) == {'kf', 'mech', 'heading_lost', 'status'}
    assert 'kf' not in set().union(*map(declared, PROTOCOLS))


def test_the_protocols_declare_exactly_what_the_stages_use():
    """The declared members equal the engine members read in align/stages and the pipeline."""
    used = set(BY_NAME)
    for path in SCANNED:
        used |= engine_reads(path.read_text())
    members = set().union(*map(declared, PROTOCOLS))
    assert used - members == set(), 'used by a stage, not declared in engines/base.py'
    assert members - used == set(), 'declared in engines/base.py, used by no stage'
    # the kind-specific members belong to one kind only
    assert not (declared(StillEngine) - declared(Engine)) & declared(AidedEngine)


def test_each_stepping_part_uses_only_its_kind():
    """The still path reads only StillEngine members, the GNSS epochs only AidedEngine's."""
    stepping = ast.parse((ALIGN / 'stages' / 'fine_stepping.py').read_text())
    parts = {c.name: engine_reads(ast.unparse(c)) for c in stepping.body
             if isinstance(c, ast.ClassDef)}
    assert parts['StillStepping'] <= declared(StillEngine)
    assert parts['AidedStepping'] <= declared(AidedEngine)
    for name in ('fine_epochs', 'motion_check', 'slow_monitor', 'course_heading'):
        assert engine_reads((ALIGN / 'stages' / f'{name}.py').read_text()) \
            <= declared(AidedEngine), name
    assert BY_NAME <= declared(AidedEngine)
    assert engine_reads((ALIGN / 'stages' / 'fine_stage.py').read_text()) <= declared(Engine)
    assert engine_reads((ALIGN / 'pipeline.py').read_text()) <= declared(Engine)


@pytest.mark.parametrize('fine_filter', prm.FINE_FILTERS)
def test_every_engine_keeps_the_contract_of_its_kind(fine_filter):
    """Each filter's engine is an Engine and exactly one kind, the one ``restages`` names."""
    cfg = {**prm.defaults(), 'fine_filter': fine_filter}
    engine, _, _ = make_engine(cfg, noise_spec(cfg), _start(), True)
    assert isinstance(engine, Engine)
    assert isinstance(engine, StillEngine) is engine.restages
    assert isinstance(engine, AidedEngine) is (not engine.restages)
    assert engine.restages is (fine_filter not in prm.MOVING_FILTERS)
    # the read-outs the stages take without asking the filter
    assert engine.attitude_cov().shape == (3, 3)
    assert engine.tilt_floor().shape == (3,)
    assert (engine.nav_cov() is None) is (not engine.navigates)
    if not engine.restages:
        assert engine.rejected is False
        assert engine.estimates_R is (fine_filter in ('vbckf', 'vbch', 'vbakf', 'mvbakf'))
