"""UFF58 channel maps as vendors' files need them: a driving point named once as the response
(the accelerometer) and once as the reference (the hammer), and messages that speak of
channels (joints or measurement points), not of joints."""

from __future__ import annotations

import numpy as np
import pytest

from bondid.data.measurement import FrfData
from bondid.data.uff_format import read_uff58, write_uff58
from bondid.exceptions import ChannelError

#: the accelerometer and the hammer on node 101 along z, a second accelerometer on node 102
MAP = {"acc1": (101, 3), "ham": (101, 3), "acc2": (102, 3)}


def _data() -> FrfData:
    f = np.geomspace(5.0, 500.0, 40)
    rng = np.random.default_rng(2)
    H = rng.normal(size=(2, 1, f.size)) + 1j * rng.normal(size=(2, 1, f.size))
    return FrfData(f, ("acc1", "acc2"), ("ham",), H, "accelerance")


@pytest.mark.parametrize("ham_dir", [3, -3])
def test_two_names_on_one_node_and_direction_round_trip(tmp_path, ham_dir):
    """The accelerometer and the hammer at node 101 along ±z: the first name is the
    response's, the second the reference's; values read back exactly, signs included."""
    d = _data()
    cmap = {"acc1": (101, 3), "ham": (101, ham_dir), "acc2": (102, 3)}
    path = write_uff58(d, tmp_path / "dp.uff", channel_map=cmap)
    r = read_uff58(path, channel_map=cmap)
    assert r.outputs == ("acc1", "acc2") and r.inputs == ("ham",)
    assert np.array_equal(r.H, d.H)
    # the map that gives the hammer the opposite direction reads the reference flipped
    flipped = read_uff58(path, channel_map={**cmap, "ham": (101, -ham_dir)})
    assert np.array_equal(flipped.H, -d.H)


def test_a_third_name_on_one_node_and_axis_is_refused_naming_channels(tmp_path):
    path = write_uff58(_data(), tmp_path / "dp.uff", channel_map=MAP)
    bad = {"acc1": (101, 3), "ham": (101, 3), "other": (101, -3), "acc2": (102, 3)}
    with pytest.raises(ChannelError) as err:
        read_uff58(path, channel_map=bad)
    msg = str(err.value)
    assert "dp.uff" in msg and "'acc1', 'ham' and 'other'" in msg and "node 101" in msg
    assert "channel names" in msg and "joint" not in msg


def test_an_invalid_name_in_the_map_is_called_a_channel_name(tmp_path):
    path = write_uff58(_data(), tmp_path / "dp.uff", channel_map=MAP)
    with pytest.raises(ChannelError, match=r"invalid channel name 'a\.1'"):
        read_uff58(path, channel_map={"a.1": (101, 3), "ham": (101, 3), "acc2": (102, 3)})


def test_write_map_missing_a_channel_names_it_as_a_channel(tmp_path):
    with pytest.raises(ChannelError, match=r"lacks channel names acc2") as err:
        write_uff58(_data(), tmp_path / "x.uff", channel_map={"acc1": (1, 3), "ham": (2, 3)})
    assert "joint" not in str(err.value)
