"""Sphinx configuration of mechsim's API reference (built by `tests/test_docs.py`, which
fails on any warning)."""
import mechsim

project = "mechsim"
release = mechsim.__version__
extensions = ["sphinx.ext.autodoc", "sphinx.ext.napoleon"]
napoleon_google_docstring = False
napoleon_numpy_docstring = True
autodoc_member_order = "bysource"
autodoc_typehints = "none"
exclude_patterns = ["_build", "design-notes.md", "benchmarks.md"]
html_theme = "alabaster"
