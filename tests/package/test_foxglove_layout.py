"""docs/foxglove_te_session.json: a Foxglove layout that Foxglove (and Lichtblick) can import.

The structure is checked against Foxglove Studio's own layout types (foxglove/studio,
packages/studio-base/src): ``LayoutData`` (context/CurrentLayoutContext/actions.ts: configById,
layout, globalVariables, userNodes), the react-mosaic tree of panel ids ``<Type>!<id>``, the
built-in panel types (panels/index.ts), ``PlotConfig`` / ``PlotPath`` (panels/Plot/types.ts,
internalTypes.ts), ``RawMessagesPanelConfig`` (panels/RawMessages/types.ts), the Table panel's
``{topicPath}`` and ``DiagnosticSummaryConfig`` (panels/diagnostics/util.ts). Every message path
is resolved against the message definitions as rosbags parses them from the .msg files, and a
Plot path must end at a number (Plot/types.ts plotableRosTypes). That the paths carry data in a
recorded session is checked in tests/launch/test_viewer_recording.py.
"""

from __future__ import annotations

import re
from typing import Any

import pytest

from tests.package.conftest import REPO, layout_paths, load_layout

# panels/index.ts (builtin), the panel types this layout may use
BUILTIN_PANEL_TYPES = {
    '3D', 'DiagnosticStatusPanel', 'DiagnosticSummary', 'ImageViewPanel', 'Indicator', 'Gauge',
    'Teleop', 'map', 'Parameters', 'Plot', 'Publish', 'RawMessages', 'RosOut',
    'StateTransitions', 'Table', 'URDFViewer', 'TopicGraph', 'SourceInfo',
    'GlobalVariableSliderPanel', 'NodePlayground', 'Tab', 'website',
}
LAYOUT_DATA_KEYS = {'configById', 'layout', 'globalVariables', 'userNodes', 'playbackConfig',
                    'version'}
PLOT_KEYS = {'title', 'paths', 'minYValue', 'maxYValue', 'showLegend', 'isSynced',
             'showTooltips', 'xAxisVal', 'xAxisPath', 'followingViewWidth'}
PLOT_REQUIRED = {'paths', 'showLegend', 'isSynced', 'showTooltips', 'xAxisVal'}
PLOT_PATH_KEYS = {'value', 'enabled', 'timestampMethod', 'color', 'label', 'showLine'}
RAW_MESSAGES_KEYS = {'diffEnabled', 'diffMethod', 'diffTopicPath', 'showFullMessageForDiff',
                     'topicPath'}
DIAGNOSTIC_SUMMARY_KEYS = {'minLevel', 'pinnedIds', 'topicToRender', 'hardwareIdFilter',
                           'sortByLevel'}
NUMERIC = {'bool', 'int8', 'uint8', 'int16', 'uint16', 'int32', 'uint32', 'int64', 'uint64',
           'float32', 'float64'}
# what the suite publishes on the topics the layout shows (README / node docstrings)
TOPIC_TYPES = {
    '/te/plot': 'rv_te_msgs/msg/TePlot',
    '/te/spectrum': 'rv_te_msgs/msg/TeSpectrum',
    '/compensation/advice': 'rv_te_msgs/msg/CompensationAdvice',
    '/diagnostics': 'diagnostic_msgs/msg/DiagnosticArray',
}


def typestore():
    from rosbags.typesys import Stores, get_types_from_msg, get_typestore

    ts = get_typestore(Stores.ROS2_JAZZY)
    for p in sorted((REPO / 'rv_te_msgs_py' / 'msg').glob('*.msg')):
        ts.register(get_types_from_msg(p.read_text(encoding='utf-8'), f'rv_te_msgs/msg/{p.stem}'))
    return ts


def resolve(path: str) -> tuple[str, bool]:
    """A Foxglove message path -> (leaf type, went through an array with [:])."""
    from rosbags.typesys.base import Nodetype

    topic, _, rest = path.partition('.')
    msgtype = TOPIC_TYPES[topic]
    ts = typestore()
    sliced = False
    current: tuple[Any, Any] = (Nodetype.NAME, msgtype)
    for part in filter(None, rest.split('.')):
        m = re.fullmatch(r'([a-z_][a-z0-9_]*)(\[:\])?', part)
        assert m, f'{path}: cannot parse {part!r}'
        assert current[0] == Nodetype.NAME, f'{path}: {part!r} is not in a message'
        fields = dict(ts.fielddefs[current[1]][1])
        assert m.group(1) in fields, f'{path}: {current[1]} has no field {m.group(1)!r}'
        current = fields[m.group(1)]
        if m.group(2):
            assert current[0] in {Nodetype.ARRAY, Nodetype.SEQUENCE}, f'{path}: [:] on a scalar'
            current = current[1][0]
            sliced = True
        else:
            assert current[0] not in {Nodetype.ARRAY, Nodetype.SEQUENCE} or part == rest.split(
                '.')[-1], f'{path}: array {part!r} needs [:]'
    leaf = current[1][0] if current[0] == Nodetype.BASE else current[1]
    return str(leaf), sliced


def mosaic_leaves(node: Any) -> list[str]:
    if isinstance(node, str):
        return [node]
    assert set(node) <= {'direction', 'first', 'second', 'splitPercentage'}, node
    assert node['direction'] in {'row', 'column'}
    assert 0 < node.get('splitPercentage', 50) < 100
    return mosaic_leaves(node['first']) + mosaic_leaves(node['second'])


def test_layout_data_and_mosaic_tree() -> None:
    doc = load_layout()
    assert set(doc) <= LAYOUT_DATA_KEYS
    assert {'configById', 'globalVariables', 'userNodes', 'layout'} <= set(doc)
    leaves = mosaic_leaves(doc['layout'])
    assert sorted(leaves) == sorted(doc['configById'])       # each panel shown exactly once
    for panel_id in leaves:
        kind, sep, name = panel_id.partition('!')
        assert sep and name and kind in BUILTIN_PANEL_TYPES, panel_id


def test_panel_configs_follow_their_types() -> None:
    for panel_id, cfg in load_layout()['configById'].items():
        kind = panel_id.split('!')[0]
        if kind == 'Plot':
            assert set(cfg) <= PLOT_KEYS and set(cfg) >= PLOT_REQUIRED, panel_id
            assert cfg['xAxisVal'] in {'timestamp', 'index', 'custom', 'currentCustom'}
            for p in cfg['paths']:
                assert set(p) <= PLOT_PATH_KEYS
                assert {'value', 'enabled', 'timestampMethod'} <= set(p)
                assert p['timestampMethod'] in {'receiveTime', 'headerStamp'}
            if cfg['xAxisVal'] in {'custom', 'currentCustom'}:
                assert set(cfg['xAxisPath']) == {'value', 'enabled'}
        elif kind == 'RawMessages':
            assert set(cfg) == RAW_MESSAGES_KEYS, panel_id
            assert cfg['diffMethod'] in {'custom', 'previous message'}
        elif kind == 'Table':
            assert set(cfg) == {'topicPath'}, panel_id
        elif kind == 'DiagnosticSummary':
            assert set(cfg) <= DIAGNOSTIC_SUMMARY_KEYS, panel_id
            assert {'minLevel', 'pinnedIds', 'topicToRender', 'hardwareIdFilter'} <= set(cfg)
        else:
            pytest.fail(f'{panel_id}: no check for this panel type')


def test_every_path_resolves_and_plots_end_at_numbers() -> None:
    paths = layout_paths()
    assert len(paths) >= 10
    for panel_id, path in paths:
        leaf, sliced = resolve(path)
        if panel_id.startswith('Plot!'):
            assert leaf in NUMERIC, f'{panel_id}: {path} ends at {leaf}, not a number'
            xaxis = load_layout()['configById'][panel_id]['xAxisVal']
            assert sliced == (xaxis in {'index', 'currentCustom'}), f'{panel_id}: {path}'
