"""Studies above the firmware and the workbench: they may import every layer below; nothing below imports them."""
