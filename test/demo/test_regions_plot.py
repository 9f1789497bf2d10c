"""
The CoM regions plot of awp_demo: its bag reading, its world alignment, the PNG.

An output bag is written here from the pipeline over the first seconds of the default gait
bag (real messages, serialised as the replay does). The regenerated gait is checked
against the evaluator on the same stamps: the stance sets and the feet relative to the CoM
(inverse kinematics of the generator vs forward kinematics of the evaluator).
"""

from __future__ import annotations

from awp_ros_msgs.msg import ContactState
import matplotlib.image
import numpy as np
import pytest
from rclpy.serialization import deserialize_message
from sensor_msgs.msg import Imu, JointState

from awp_ros.bags.message_types import OUTPUT_TYPES, serialize
from awp_ros.bags.reader import BagMessage, read_bag
from awp_ros.bags.writer import BagWriter
from awp_ros.demo.regions_plot import (_instants, demo_regions_plot, gait_world, plot_regions,
                                       read_regions)
from awp_ros.gait.bag import default_bag_path
from awp_ros.robot.parameters import PipelineParams
from awp_ros.ros.pipeline import Pipeline

SECONDS = 2.6           # the first crawl swing starts at 1.1 s
EVERY = 5               # every 5th joint state (100 Hz)
NAMES = ('report', 'feasible_region', 'support_region')


@pytest.fixture(scope='module')
def run(tmp_path_factory):
    """Return (bag path, results by stamp [ns]) of the pipeline over the gait's start."""
    out = tmp_path_factory.mktemp('regions') / 'out.mcap'
    pl = Pipeline('hyq', PipelineParams(use_imu=True))
    classes = {'/joint_states': JointState, '/contacts': ContactState, '/imu': Imu}
    results = {}
    seen = 0
    with BagWriter(out) as writer:
        for m in read_bag(default_bag_path(), topics=list(classes)):
            obj = deserialize_message(m.data, classes[m.topic])
            if m.topic == '/contacts':
                pl.on_contacts(obj)
                continue
            if m.topic == '/imu':
                pl.on_imu(obj)
                continue
            ns = obj.header.stamp.sec * 10**9 + obj.header.stamp.nanosec
            seen += 1
            if (seen - 1) % EVERY:
                continue
            if ns - 1_704_067_200 * 10**9 > SECONDS * 1e9:
                break
            cycle = pl.on_joint_state(obj)
            results[ns] = cycle.result
            for name in NAMES:
                msg = cycle.report if name == 'report' else getattr(cycle, name)()
                if msg is not None:
                    writer.write(BagMessage(f'/awp_node/{name}', OUTPUT_TYPES[name],
                                            m.timestamp, serialize(msg, OUTPUT_TYPES[name])))
    return out, results


def test_read_regions_returns_what_the_pipeline_sent(run):
    bag, results = run
    track = read_regions(bag)
    assert track.stamps.tolist() == sorted(results)
    assert track.valid.all() and len(track.support) == len(results)
    assert len(track.feasible) == len(results)                 # every cycle (projection)
    for i, ns in enumerate(track.stamps.tolist()):
        r = results[ns]
        np.testing.assert_allclose(track.support[ns], r.support_region.vertices, atol=1e-6)
        assert track.margins['support_region'][i] == r.support_region.margin
        assert track.margins['fwp_region'][i] == r.fwp_region.margin
        assert track.stance[i] == len(r.stance)
        if ns in track.feasible and r.feasible_region is None:     # not computed: warned
            assert track.feasible[ns].shape == (0, 2)
            assert any('feasible region not computed' in w for w in r.warnings)
        elif ns in track.feasible:
            np.testing.assert_allclose(track.feasible[ns], r.feasible_region.vertices,
                                       atol=1e-6)
            assert track.margins['feasible_region'][i] == r.feasible_region.margin
        else:
            assert np.isnan(track.margins['feasible_region'][i])
    picks = _instants(track, 4)
    assert len(picks) == 4 and picks == sorted(picks)
    assert {int(track.stance[i]) for i in picks} == {3, 4}      # both stance counts shown
    assert all(int(track.stamps[i]) in track.feasible for i in picks)


def test_gait_world_is_aligned_with_the_bag(run):
    bag, results = run
    track = read_regions(bag)
    world = gait_world(track.stamps)
    for i, ns in enumerate(track.stamps.tolist()):
        r = results[ns]
        assert world.stance[i].sum() == len(r.stance)
        feet = world.feet[i][world.stance[i]] - world.com[i]
        mine = np.array([leg.position for leg in r.legs.values()])
        np.testing.assert_allclose(feet, mine, atol=1e-4)        # q rounded in the bag
    assert np.all(np.isfinite(world.com_velocity))


def test_plot_regions_writes_a_png_with_and_without_the_world(run, tmp_path):
    bag, _ = run
    track = read_regions(bag)
    png = demo_regions_plot(bag, tmp_path / 'r.png', default_bag_path(), title='test')
    image = matplotlib.image.imread(png)
    assert image.shape[0] > 600 and image.shape[1] > 800
    green = np.array([0x1b, 0x9e, 0x77]) / 255.0                  # the feasible region
    assert np.mean(np.all(np.abs(image[..., :3] - green) < 0.25, axis=-1)) > 0.002
    plain = plot_regions(track, tmp_path / 'plain.png', world=None, instants=3)
    assert plain.read_bytes()[:8] == b'\x89PNG\r\n\x1a\n'


def test_demo_regions_plot_skips_a_bag_without_regions(tmp_path, capsys):
    assert demo_regions_plot(default_bag_path(), tmp_path / 'x.png', default_bag_path()) is None
    assert 'skipped' in capsys.readouterr().out and not (tmp_path / 'x.png').exists()
