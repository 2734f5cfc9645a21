"""Case files: the schema (:mod:`.schema`) and the YAML loader (:mod:`.loader`)."""

from .loader import CaseErrors, Source, format_key, load_case
from .schema import Case

__all__ = ["Case", "CaseErrors", "Source", "format_key", "load_case"]
