"""hcvt.experiments: each experiment carries its dimension, its table and the paper's values."""

import pytest

from hcvt.experiments import EXPERIMENTS, PAPER, Summary, experiments

DIM = {"square": 2, "star": 2, "ball": 3}  # anything else is a mesh of ../shared/data/3d


@pytest.mark.parametrize("quick", [False, True])
def test_every_experiment_knows_its_dimension(quick):
    for name, experiment in experiments(quick).items():
        dims = {DIM.get(c.shape, 3) for c in experiment.configs}
        expected = dims.pop() if len(dims) == 1 else None
        assert experiment.dim == expected, name


def test_reproduce_all_runs_the_tables_then_figure_12():
    assert EXPERIMENTS[:8] == tuple(f"table{k}" for k in range(2, 9)) + ("fig12",)


def test_the_paper_values_reach_the_rows():
    table4 = experiments(False)["table4"]
    assert [(c.paper_g, c.paper_energy) for c in table4.configs] == list(PAPER["table4"].values())
    table3 = experiments(True)["table3"]
    assert tuple(c.paper_g for c in table3.configs) == PAPER["table3"]


def test_level_sizes_follow_the_schedule():
    table2 = experiments(False)["table2"]
    summary = Summary(table2.configs[0], [{"levels_G": list(PAPER["table2"])}])
    lines = table2.table(table2, [summary]).splitlines()[2:]
    assert [int(line.split("|")[2]) for line in lines] == [10, 40, 160, 640, 2560]
    assert all(line.endswith("| 1.0000 |") for line in lines)
