"""``crowd report`` pedestrian measures (crowd.report.pedestrian, PedPy) against a hand computation.

Ten agents in single file, 1 m apart, walk at 1 m/s along +z (goals, no avoidance) through a 2 m x 2.5 m
measurement area and across a 2 m line at z = 0: flow = speed / spacing = 1 person/s, every speed 1 m/s, the
density of each frame = agents inside / 5 m^2.
"""
import json
import re

import numpy as np
import pytest
from crowd_testutil import run_cli

from crowd.report.pedestrian import weidmann_speed
from crowd.trajectories import read_trajectories

pytest.importorskip("pedpy")  # the report extra; installed by make setup

LINE_SCENE = """\
name = "single_file"
seed = 1
dt = 0.1
frames = 150
effects = [{ name = "goals", paths = [[[0.0, 200.0]]], loop = false, speed = 1.0, arrive_radius = 0.01 }]

[[characters]]
name = "walker"
generator = "humanoid"
triangles = 600

[[placement]]
kind = "grid"
character = "walker"
rows = 10
cols = 1
spacing = [1.0, 1.0]
origin = [0.0, 0.0, -12.0]

[[measurement]]
name = "area"
polygon = [[-1.0, -2.0], [1.0, -2.0], [1.0, 0.5], [-1.0, 0.5]]
line = [[-1.0, 0.0], [1.0, 0.0]]

[camera]
position = [1.0, 2.0, 7.0]
target = [1.0, 0.8, 1.0]

[render]
size = [64, 48]
"""


@pytest.fixture(scope="module")
def report(tmp_path_factory):
    d = tmp_path_factory.mktemp("ped")
    scene = d / "single_file.toml"
    scene.write_text(LINE_SCENE)  # no [output] trajectories: the report turns them on for its first run
    out = d / "report"
    r = run_cli("report", scene, "--cluster", "none", "--out", out, "--quiet", timeout=600)
    assert r.returncode == 0, r.stderr
    return out


def test_page_has_the_table_with_hand_computed_numbers(report):
    html = (report / "index.html").read_text()
    rows = re.findall(r"<tr class='measurement'>(.*?)</tr>", html)
    assert len(rows) == 1
    cells = re.findall(r"<td[^>]*>(.*?)</td>", rows[0])
    name, area, occupied, density, voronoi, speed, jrho, crossings, flow, spec, wflow = cells
    assert name == "area" and float(area) == 5.0
    assert float(speed) == pytest.approx(1.0, abs=1e-3)  # every agent walks 1 m/s
    assert int(crossings) == 10
    assert float(flow) == pytest.approx(1.0, abs=1e-3)  # 1 m/s / 1 m spacing
    assert float(spec) == pytest.approx(0.5, abs=1e-3)  # over a 2 m line
    assert float(density) == pytest.approx(float(jrho), abs=1e-3)  # v = 1: rho v = rho
    for rel in re.findall(r"<img src='(plots/single_file_meas0_[a-z]+\.png)'", html):
        assert (report / rel).stat().st_size > 1000
    assert len(re.findall(r"plots/single_file_meas0_", html)) == 2  # time series and fundamental diagram


def test_density_series_is_the_hand_count(report):
    data = json.loads((report / "report.json").read_text())
    ped = data["scenes"][0]["pedestrian"]
    area = ped["measurements"][0]["area"]
    _, traj = read_trajectories(report / ped["trajectories"])
    # hand count: agents strictly inside -1 < x < 1, -2 < z < 0.5 (PedPy's y) per frame, / 5 m^2 (an agent on
    # the border, z = -2.0000 in the file, is outside, as for PedPy's shapely `within`)
    inside = (np.abs(traj[:, 2]) < 1.0) & (traj[:, 3] > -2.0) & (traj[:, 3] < 0.5)
    count = np.bincount(traj[inside, 1].astype(int), minlength=150)
    frames = np.array(area["frames"])
    assert np.array_equal(frames, np.nonzero(count)[0])
    np.testing.assert_allclose(area["density"], count[frames] / 5.0)
    assert area["mean_density"] == pytest.approx(np.mean(count[frames] / 5.0))
    line = ped["measurements"][0]["line"]
    assert line["cumulative"][-1] == 10 and line["mean_flow"] == pytest.approx(1.0, abs=1e-9)
    # the first agent across starts at z = -3 (1 m/s): it reaches z = 0 after 3 s, the others 1 s apart
    t_cross = np.array(line["time"])[np.diff(np.r_[0, line["cumulative"]]) > 0]
    np.testing.assert_allclose(t_cross, np.arange(3.0, 13.0), atol=0.11)


def test_weidmann_reference_curve():
    assert float(weidmann_speed(5.4)) == 0.0 and float(weidmann_speed(8.0)) == 0.0
    assert float(weidmann_speed(1e-9)) == pytest.approx(1.34)
    assert float(weidmann_speed(1.0)) == pytest.approx(1.34 * (1 - np.exp(-1.913 * (1 - 1 / 5.4))))
    assert np.all(np.diff(weidmann_speed(np.linspace(0.1, 5.4, 50))) < 0)  # decreasing


def test_empty_area_and_uncrossed_line(tmp_path):
    from crowd.measurement import MeasurementSpec
    from crowd.report.pedestrian import analyse, plots
    from crowd.trajectories import TrajectoryWriter

    p = tmp_path / "t.txt"
    with TrajectoryWriter(p, "t", 3, 0.1) as w:
        for f in range(20):
            w.write(f, np.array([[0.0, 0.0, 0.1 * f], [1.0, 0.0, 0.1 * f], [2.0, 0.0, 0.1 * f]]))
    far = MeasurementSpec("far", polygon=((50, 50), (51, 50), (51, 51)), line=((50, 0), (51, 0)))
    (m,) = analyse(p, [far])
    assert m["area"]["frames_occupied"] == 0 and m["area"]["mean_density"] is None and m["area"]["density"] == []
    assert m["line"]["crossings"] == 0 and m["line"]["mean_flow"] is None and m["line"]["specific_flow"] is None
    (tmp_path / "plots").mkdir()
    paths = plots(tmp_path, "s", "t", [m])
    assert paths["far"]["fd"] is None and (tmp_path / paths["far"]["series"]).is_file()
