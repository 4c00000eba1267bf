"""The shipped scenes (the repository's scenes/ folder, installed as sandbox.scenes)."""
