"""The one error type the add-on raises; the operator turns it into a Blender report."""


class LensblurError(Exception):
    """A problem the user can fix; the message says how."""
