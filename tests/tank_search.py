"""A diagnosis search (:class:`pipeline.diagnose.select.Search`) on the virtual tank's runs, for tests
that drive the selection's steps by hand."""

from __future__ import annotations

from pipeline import tank
from pipeline.config import DiagnoseConfig, TankConfig
from pipeline.diagnose.core import _context
from pipeline.diagnose.fit import series_from_run, with_initial_states
from pipeline.diagnose.select import Fold, Search


def tank_search(train, validate, **cfg_kw) -> Search:
    """The virtual tank's (:func:`pipeline.tank.simulate`, default TankConfig) runs of the manoeuvres
    ``train`` and ``validate`` as a search of two folds (training on either side, the other held out),
    their start states set as the diagnosis sets them; ``cfg_kw`` DiagnoseConfig fields.  No fit memo:
    every fit is made."""
    tr = [series_from_run(tank.simulate(m, TankConfig())) for m in train]
    va = [series_from_run(tank.simulate(m, TankConfig())) for m in validate]
    ctx, cfg = _context(tr + va), DiagnoseConfig(**cfg_kw)
    tr, va = (with_initial_states(x, cfg.x0_window_T * ctx.t_ship, cfg.x0_model_window_T * ctx.t_ship,
                                  cfg.x0_box_sigma) for x in (tr, va))
    return Search([Fold(tr, va), Fold(va, tr)], ctx, cfg)
