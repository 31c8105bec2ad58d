"""toolkit.measure.lanes_timing's arithmetic and table, on made-up rates (its timing loop runs in
tutorials 02 and 03, in the documentation's build, where Intel's runtime is installed)."""
from toolkit.measure.lanes_timing import format_lanes_table, intel_runtime, ratio_in_each_run

RATES = {("a", "off"): [100.0, 50.0, 90.0], ("b", "off"): [50.0, 50.0, 30.0],
         ("a", "on"): [10.0, 20.0, 30.0], ("b", "on"): [20.0, 20.0, 20.0]}


def test_the_ratio_is_the_median_of_each_runs_ratio():
    # run by run a/b = 2, 1, 3 with lanes off: median 2; the ratio of medians would be 90/50 = 1.8
    assert ratio_in_each_run(RATES, "a", "b", "off") == 2.0
    assert ratio_in_each_run(RATES, "a", "b", "on") == 1.0     # 0.5, 1, 1.5


def test_the_table_has_a_row_per_technique_with_both_ratios_and_the_talks():
    lines = format_lanes_table(RATES, "b", {"a": "~1.20", "b": "1.00"}).splitlines()
    a = lines[1].split()
    assert a[0] == "a" and a[1:] == ["90", "20", "2.00", "1.00", "~1.20"]
    assert lines[2].split() == ["b", "50", "20", "1.00", "1.00", "1.00"]


def test_a_vectorizer_fixed_by_the_environment_is_named_and_nothing_is_timed(monkeypatch):
    # Intel's runtime reads the variable once, for the whole process: lanes on and off cannot both
    # be timed then, whether or not the runtime is installed here.
    monkeypatch.setenv("CL_CONFIG_USE_VECTORIZER", "False")
    runtime, why = intel_runtime()
    assert runtime is None and "CL_CONFIG_USE_VECTORIZER=False" in why and "unset it" in why


def test_where_intel_is_missing_or_usable_it_says_which(monkeypatch):
    monkeypatch.delenv("CL_CONFIG_USE_VECTORIZER", raising=False)
    monkeypatch.delenv("CL_CONFIG_CPU_VECTORIZER_MODE", raising=False)
    runtime, why = intel_runtime()
    if runtime is None:
        assert why and ("Intel" in why or "x86-64" in why), why
    else:
        assert why is None and "Intel" in runtime.device.platform.name
