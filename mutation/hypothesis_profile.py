"""pytest plugin loaded for mutant runs only (``PYTEST_PLUGINS``, set by mutation/mutate.py): hypothesis finds a
failing example but does not shrink it — a mutant only needs one failure, and shrinking can take minutes."""

from hypothesis import Phase, settings

settings.register_profile("mutation", phases=[Phase.explicit, Phase.reuse, Phase.generate], deadline=None,
                          print_blob=False)
settings.load_profile("mutation")
