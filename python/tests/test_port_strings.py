"""The table of port strings every front end is tested against
(crates/firelink-testbed/port-strings.tsv): Python reads each the same way
as the command line, the web console and the ROS 2 node, or refuses it
with the same words."""

import pathlib

import pytest

import firelink

TABLE = pathlib.Path(__file__).resolve().parents[2] / "crates" / "firelink-testbed" / "port-strings.tsv"


def rows():
    for line in TABLE.read_text().splitlines():
        if line.strip() and not line.startswith("#"):
            text, meaning = line.split("\t", 1)
            yield text, meaning


ROWS = list(rows())


def test_the_table_is_there():
    assert len(ROWS) >= 30
    assert any(m.startswith("refused:") for _, m in ROWS)


@pytest.mark.parametrize("text,meaning", ROWS)
def test_python_reads_each_port_string_as_the_table_says(text, meaning):
    if meaning.startswith("refused:"):
        says = meaning.removeprefix("refused:")
        with pytest.raises(firelink.PortError) as parsed:
            firelink.parse_port(text)
        assert says in str(parsed.value)
        # Opening it is refused with the same words.
        with pytest.raises(firelink.PortError) as opened:
            firelink.open(text)
        assert says in str(opened.value)
    else:
        assert firelink.parse_port(text) == meaning
        assert firelink.parse_port(meaning) == meaning
        if meaning.startswith("sim"):
            # The simulated ports open: the name is the port written back.
            assert firelink.open(text).name == meaning


def test_sim_means_the_dvrk_boards_and_emulate_is_refused_by_name():
    boards = firelink.open("sim:8").scan()
    assert [b.board_id for b in boards] == list(range(8))
    with pytest.raises(firelink.PortError, match="firelink.open: port emulate cannot be used"):
        firelink.open("emulate")
    with pytest.raises(firelink.PortError, match="firelink.SnakeSystem: port sim:4 cannot be used"):
        firelink.SnakeSystem("sim:4")
