"""Report figure helpers (pipeline/report/nb.py): what a reader sees on an axis."""

from __future__ import annotations

import matplotlib

matplotlib.use("Agg")

import matplotlib.pyplot as plt  # noqa: E402

from pipeline.report import nb  # noqa: E402


def test_log_axes_are_labelled_in_plain_numbers():
    """With mathtext off (nb.setup), matplotlib's default log labels would print as '$\\mathdefault
    {10^{1}}$'; plain_log_ticks labels the decades 0.01 ... 10 as numbers and leaves linear axes."""
    nb.setup()
    fig, (ax, lin) = plt.subplots(2)
    ax.semilogy([0, 1, 2], [0.01, 1.0, 10.0])
    lin.plot([0, 1], [0, 1])
    before = lin.yaxis.get_major_formatter()
    nb.plain_log_ticks(fig)
    fig.canvas.draw()
    labels = [t.get_text() for t in ax.get_yticklabels() if t.get_text()]
    assert {"0.01", "0.1", "1", "10"} <= set(labels)
    assert not any("$" in s or "mathdefault" in s for s in labels)
    assert lin.yaxis.get_major_formatter() is before
    plt.close(fig)


def test_each_page_numbers_its_own_tables_and_figures(monkeypatch):
    """The numbers live in the Page setup() returns: two pages count independently, and the module's
    show/table (for a notebook that has not taken its page) use the page of the last setup()."""
    import IPython.display
    import pandas as pd

    shown: list[str] = []
    monkeypatch.setattr(IPython.display, "display",
                        lambda obj: shown.append(getattr(obj, "data", None) or "<figure>"))
    first = nb.setup()
    df = pd.DataFrame({"K (1/s)": [0.39]}, index=["identified"])
    first.table(df, "one")
    first.table(df, "two")
    second = nb.setup()
    second.table(df, "three")
    fig, _ = plt.subplots()
    second.show(fig, "a figure")
    second.table(df, "four")
    assert (first.tables, first.figures, second.tables, second.figures) == (2, 0, 2, 1)
    captions = [s for s in shown if "Table " in s or "Figure " in s]
    assert ["Table 1. one" in captions[0], "Table 2. two" in captions[1], "Table 1. three" in captions[2],
            "Figure 1.</b> a figure" in captions[3], "Table 2. four" in captions[4]] == [True] * 5
    assert 'id="T_tab1"' in captions[2]       # the table id follows the page's number: same bytes
