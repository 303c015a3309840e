"""The web UI (viser): a 3D drape view and a flat pattern view, each on its own
viser server, shown side by side on one page. Importable without the bus.

    from couture.ui import CoutureUI, UIConfig
"""

from couture.ui.app import CoutureUI, UIConfig

__all__ = ["CoutureUI", "UIConfig"]
