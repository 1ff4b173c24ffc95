"""The coordinated fleet controller: settings (:mod:`.config`), the plan's map (:mod:`.cellmap`),
planning (:mod:`.planning`) and execution (:mod:`.execution`), put together in :mod:`.controller`."""

from bulletnav.fleet.coordinated.config import CoordinatedConfig
from bulletnav.fleet.coordinated.controller import CoordinatedController

__all__ = ["CoordinatedConfig", "CoordinatedController"]
