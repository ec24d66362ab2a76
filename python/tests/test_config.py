"""Configurations: the shipped files load; bad ones say file, path and problem."""

import json

import pytest

import firelink


def test_the_shipped_configurations_load(configs_dir):
    dvrk = firelink.load_config(configs_dir / "dvrk-seed000.json")
    assert dvrk.robots == ["MTML", "MTMR", "PSM1", "PSM2"]
    assert dvrk.joints == 28
    assert sorted(dvrk.boards) == list(range(8))
    again = firelink.parse_config(dvrk.to_json())
    assert again.robots == dvrk.robots
    # Every saw-robot-io configuration shipped loads (the MAHRU humanoid's
    # file is seed 002's own module system, not a saw-robot-io file).
    robot_io = [p for p in configs_dir.glob("*.json") if "$id" in json.loads(p.read_text())]
    assert len(robot_io) >= 7
    for path in robot_io:
        firelink.load_config(path)


def test_a_bad_value_names_file_path_and_problem(configs_dir):
    data = json.loads((configs_dir / "bench-1board.json").read_text())
    data["robots"][0]["number_of_actuators"] = 99
    with pytest.raises(firelink.ConfigError) as caught:
        firelink.parse_config(json.dumps(data), file="broken.json")
    e = caught.value
    assert e.file == "broken.json"
    assert "number_of_actuators" in e.path or "actuators" in e.path
    assert e.problem
    assert "broken.json" in str(e)
    assert isinstance(e, ValueError)


@pytest.mark.parametrize("text", ["", "{", "[]", '{"robots": 3}', "null"])
def test_garbage_is_a_config_error(text):
    with pytest.raises(firelink.ConfigError):
        firelink.parse_config(text)


def test_a_missing_file_is_a_config_error(tmp_path):
    with pytest.raises(firelink.ConfigError) as caught:
        firelink.load_config(tmp_path / "absent.json")
    assert "absent.json" in caught.value.file
