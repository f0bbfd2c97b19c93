"""Where the outside data the tests read lives: ``../shared/data`` beside the repository (real recordings
and public datasets the repository does not carry); tests that need it skip, saying so, when it is absent."""

from pathlib import Path

SHARED_DATA = Path(__file__).resolve().parents[1].parent / "shared" / "data"
