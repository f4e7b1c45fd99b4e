"""Progress of a solve: a tqdm bar over pseudo-time (notebooks, terminals)
or log records on the ``skfem_rod`` logger.

``Rod.solve(..., progress=True)`` uses :func:`step_reporter`; without tqdm
installed (``pip install 'skfem_rod[progress]'``) the steps go to
:mod:`logging` at INFO instead, shown once a handler is configured
(``logging.basicConfig(level=logging.INFO)``).

>>> from skfem_rod import Rod, Section, geometry
>>> rod = Rod(geometry.straight(1.0), Section.circle(E=1e7, nu=0.3, radius=0.01), 4)
>>> result = rod.clamp("start").add_force("end", [0.0, 0.01, 0.0]).solve(2, progress="log")
>>> result.converged
True
"""
import logging

log = logging.getLogger("skfem_rod.progress")


def _describe(step):
    text = f"load factor {step.load_factor:.6g}, Newton {step.iterations}"
    contact = step.contact
    if contact is not None:
        text += f", contacts {len(contact.s)}"
    return text


def step_reporter(progress, callback=None):
    """A per-step callback ``f(result, k)`` reporting progress, and the
    function that closes the report.

    Parameters
    ----------
    progress : bool or {"bar", "log"}
        ``True`` or ``"bar"``: a tqdm bar over pseudo-time (``tqdm.auto``, a
        widget in notebooks), or log records if tqdm is missing; ``"log"``:
        an INFO record per converged step on the ``skfem_rod.progress``
        logger; ``False``: nothing (``callback`` returned unchanged).
    callback : callable, optional
        The user's own ``callback(result, k)``, still called after the report.

    Returns
    -------
    callback : callable or None
    close : callable
    """
    if progress not in (True, False, "bar", "log"):
        raise ValueError(f"progress must be True, False, 'bar' or 'log', got {progress!r}")
    if not progress:
        return callback, lambda: None
    bar = None
    if progress is True or progress == "bar":
        try:
            from tqdm.auto import tqdm
        except ImportError:
            log.info("tqdm is not installed (pip install 'skfem_rod[progress]'): "
                     "progress goes to the log")
        else:
            bar = tqdm(total=1.0, unit="", desc="solve",
                       bar_format="{desc}: {percentage:3.0f}%|{bar}| [{elapsed}{postfix}]")

    def report(result, k):
        step = result.steps[k]
        if bar is not None:
            bar.update(max(0.0, float(step.time) - bar.n))
            bar.set_postfix_str(_describe(step), refresh=True)
        else:
            log.info("step %d: %s", k, _describe(step))
        if callback is not None:
            callback(result, k)

    def close():
        if bar is not None:
            bar.close()
    return report, close
