"""The held-out scene generator (make_scene.py); a package so that mypy tells it from
tools/white_room/make_scene.py."""
