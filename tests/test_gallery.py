"""The gallery's pictures (examples/gallery.py, docs/gallery.md): every analysis draws, and
every labelled axis carries its unit."""

import importlib.util
import re
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]


def load_gallery():
    spec = importlib.util.spec_from_file_location("gallery", ROOT / "examples" / "gallery.py")
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    return module


def test_every_gallery_picture_labels_its_axes_with_units():
    gallery = load_gallery()
    figures = gallery.figures(quick=True)
    assert set(figures) == set(gallery.GALLERY)
    unit = re.compile(r"\[[^\]]+\]\s*$")
    for name, fig in figures.items():
        labelled = 0
        for ax in fig.axes:
            for label in (ax.get_xlabel(), ax.get_ylabel()):
                if label:
                    labelled += 1
                    assert unit.search(label), (name, label)
            assert ax.lines or ax.patches or ax.collections, (name, "an empty axis")
        assert labelled >= 2, name
    page = (ROOT / "docs" / "gallery.md").read_text()
    for name in gallery.GALLERY:
        assert f"images/gallery_{name}.png" in page
        assert (ROOT / "docs" / "images" / f"gallery_{name}.png").stat().st_size > 10_000
