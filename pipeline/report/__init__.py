"""Reports: parameterised notebooks (``notebooks/*.py``, jupytext percent format) executed with
papermill on the ``tanktest`` kernel and rendered to self-contained HTML in ``reports/``.

:mod:`pipeline.report.render` runs and converts the notebooks; :mod:`pipeline.report.nb` holds the
helpers the notebooks import (loading stage outputs, the provenance banner, tables, plot defaults),
so that the notebooks stay thin and read only stage outputs.
"""

from pipeline.report.render import (
    NOTEBOOKS,
    Report,
    check_inputs,
    ensure_kernel,
    render,
    render_all,
    required_inputs,
    to_html,
    write_index,
)

__all__ = ["NOTEBOOKS", "Report", "check_inputs", "ensure_kernel", "render", "render_all",
           "required_inputs", "to_html", "write_index"]
