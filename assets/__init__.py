"""The shipped assets: the materials library and masks (the top-level assets/ folder, installed as sandbox.assets)."""
