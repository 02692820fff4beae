"""Progress bars (tqdm, an optional extra: `pip install tqdm`, or `pip install '.[progress]'` from a checkout), imported only
when one is asked for."""

from __future__ import annotations

import warnings


def tqdm_bar(**options):
    """A `tqdm.auto.tqdm` with `options`, or None with a warning where tqdm is not
    installed (the work goes on without a bar)."""
    try:
        from tqdm.auto import tqdm
    except ImportError:
        warnings.warn("mechsim: progress=True needs tqdm (pip install tqdm; from a checkout, pip install '.[progress]'); "
                      "running without a progress bar", stacklevel=4)
        return None
    return tqdm(**options)
