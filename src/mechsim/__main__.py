"""`python -m mechsim ...`: the `mechsim` command."""
import sys

from .app.cli import main

sys.exit(main())
