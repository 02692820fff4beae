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


class Progress:
    """A progress bar of simulated time (tqdm, where it is installed; without it a warning
    once and no bar)."""

    def __init__(self, t_start, t_end, title):
        self.t = t_start
        self.bar = tqdm_bar(total=t_end - t_start, desc=title, unit="s", unit_scale=True,
                            bar_format="{desc}: {percentage:3.0f}%|{bar}| t = {n:.4g} of "
                                       "{total:.4g} s [{elapsed}<{remaining}]")

    def update(self, t):
        if self.bar is not None and t > self.t:
            self.bar.update(t - self.t)
            self.t = t

    def close(self):
        if self.bar is not None:
            self.bar.close()
