"""Recently opened DICOM folders, kept in QSettings (most recent first)."""

from __future__ import annotations

from PySide6.QtCore import QSettings

#: How many folders the list keeps.
MAX_RECENT = 8
KEY = "recent_folders"


class RecentFolders:
    """The recent-folder list of ``settings``."""

    def __init__(self, settings: QSettings) -> None:
        self.settings = settings

    def items(self) -> list[str]:
        """Most recent first."""
        value = self.settings.value(KEY, [])
        if isinstance(value, str):  # QSettings returns a lone string for a one-item list
            return [value]
        if isinstance(value, list | tuple):
            return [str(v) for v in value]
        return []

    def remember(self, path: str) -> list[str]:
        """Put ``path`` first (once), keep ``MAX_RECENT``, save; returns the new list."""
        items = [path] + [p for p in self.items() if p != path]
        self.settings.setValue(KEY, items[:MAX_RECENT])
        self.settings.sync()
        return items[:MAX_RECENT]
