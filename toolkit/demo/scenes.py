"""The scenes the page may choose from: the bundled ones, and the folder given on the command line.

What the browser sends is untrusted: it names a scene by a key of this list, and only the paths
stored here at start-up are ever opened. A key that is not in the list is an error; a path typed
into the page is never joined to anything.
"""
from pathlib import Path

from toolkit.core.scene import SceneError, bundled_scene_dir, bundled_scene_names, find_scene, load_scene
from toolkit.core.validate import InputError


class SceneChoices:
    """{key: scene folder}, checked once: the bundled scenes and `given` (a scene folder, its
    scene.json, a folder of scene folders, or a bundled scene's name)."""

    def __init__(self, given=None):
        self.paths = {name: bundled_scene_dir(name) for name in bundled_scene_names()}
        self.first = "cornell_box"
        if given is not None:
            self.first = self.add_given(given)

    def add_given(self, given):
        """Add the command line's scene(s); returns the key to show first. SceneError if there is none."""
        path = find_scene(given)        # the one resolver of every command: a path, or a bundled scene's name
        if not Path(given).exists():    # a bundled scene by name (`demo covered_lamp`): listed already
            return path.name
        if path.is_file():
            folders = [path.parent]
        elif (path / "scene.json").is_file():
            folders = [path]
        else:
            folders = sorted(p.parent for p in path.glob("*/scene.json"))
            if not folders:
                raise SceneError(f"{given}: no scene.json there, nor in the folders inside it")
        keys = []
        for folder in folders:
            load_scene(folder)      # a bad scene stops the start-up with its own message
            key = folder.resolve().name
            if key in self.paths:
                key = f"{key} ({folder})"
            self.paths[key] = folder.resolve()
            keys.append(key)
        return keys[0]

    def names(self):
        return list(self.paths)

    def path(self, key):
        """The folder of the scene named `key` (from the browser: checked against the list)."""
        if not isinstance(key, str) or key not in self.paths:
            raise InputError(f"unknown scene {str(key)[:80]!r}: the demo opens only the bundled scenes and the folder "
                             f"given on its command line ({', '.join(self.paths)})")
        return self.paths[key]

    def load(self, key):
        return load_scene(self.path(key))
