"""``python -m plane_validation``: the command line, as ``plane-validation`` (:mod:`plane_validation.cli`)."""
import sys

from .cli import main

sys.exit(main())
