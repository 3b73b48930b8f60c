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
