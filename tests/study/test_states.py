"""A run's state from its fold count: arc, folded, multi-folded."""

from hydrojam.study.states import state_counts, state_of, states_text


def test_a_runs_state_is_read_from_its_fold_count():
    """0 folds: one arc; 1: folded (the 3D default design at 275 K); 2 or more: multi-folded (the
    3D design with a 4 mm strip, whose column folds back on itself and bends half as far)."""
    assert state_of({"column_folds": 0}) == "arc"
    assert state_of({"column_folds": 1}) == "folded"
    assert state_of({"column_folds": 2}) == state_of({"column_folds": 3}) == "multi-folded"
    assert state_of({}) is None and state_of(None) is None and state_of({"column_folds": float("nan")}) is None


def test_a_points_states_cell_names_each_state_with_its_runs():
    counts = state_counts(["folded", "multi-folded", None, "folded"])
    assert counts == {"folded": 2, "multi-folded": 1}
    assert states_text(counts) == "folded 2; multi-folded 1"
    assert states_text(state_counts(["arc", "arc"])) == "arc"
    assert states_text({}) is None
