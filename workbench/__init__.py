"""Model workbench: measurements in, model replayed, where it fails, which effect is missing, refit."""
