"""Builds the Blender Extension package of the add-on (Blender 4.2+, Preferences > Get
Extensions > Install from Disk): a zip of plugins/blender/lensblur/ with blender_manifest.toml
at its root, as `blender --command extension build` lays it out. Needs only Python 3.11+ (no
Blender, no lensblur), so it runs on any machine that packages the add-on.

Usage: python3 plugins/blender/build_extension.py [--legacy] [-o OUT.zip]
(default: plugins/blender/lensblur-extension.zip). With --legacy, the zip for Blender 3.4 to 4.1
(Preferences > Add-ons > Install) instead: the same files in a `lensblur/` folder (default:
plugins/blender/lensblur.zip). Refuses a manifest whose version disagrees with the legacy
`bl_info` of __init__.py (what Blender 3.4 to 4.1 read)."""
import argparse
import ast
import os
import sys
import tomllib
import zipfile

HERE = os.path.dirname(os.path.abspath(__file__))
ADDON = os.path.join(HERE, "lensblur")
MANIFEST = "blender_manifest.toml"
# What Blender's own builder leaves out too: bytecode caches and editor droppings.
SKIPPED_DIRS = {"__pycache__", ".git"}
SKIPPED_SUFFIXES = (".pyc", ".pyo", "~", ".swp")
REQUIRED = ("schema_version", "id", "version", "name", "tagline", "maintainer", "type", "blender_version_min", "license")


def legacy_bl_info(init_path):
    """`bl_info` of the add-on's __init__.py, read without importing it (it imports bpy)."""
    with open(init_path) as f:
        tree = ast.parse(f.read(), init_path)
    for node in tree.body:
        if isinstance(node, ast.Assign) and any(getattr(t, "id", None) == "bl_info" for t in node.targets):
            return ast.literal_eval(node.value)
    raise SystemExit(f"{init_path}: no bl_info")


def check_manifest(manifest, bl_info):
    missing = [key for key in REQUIRED if key not in manifest]
    if missing:
        raise SystemExit(f"{MANIFEST}: missing {', '.join(missing)}")
    if manifest["type"] != "add-on":
        raise SystemExit(f"{MANIFEST}: type is {manifest['type']!r}, expected 'add-on'")
    legacy_version = ".".join(str(part) for part in bl_info["version"])
    if manifest["version"] != legacy_version:
        raise SystemExit(
            f"{MANIFEST} version {manifest['version']} != bl_info version {legacy_version} in __init__.py: "
            "bump both"
        )


def packaged_files(root):
    """(path on disk, path in the zip) of every file of the add-on, sorted."""
    files = []
    for directory, subdirs, names in os.walk(root):
        subdirs[:] = sorted(d for d in subdirs if d not in SKIPPED_DIRS)
        for name in sorted(names):
            if not name.endswith(SKIPPED_SUFFIXES):
                path = os.path.join(directory, name)
                files.append((path, os.path.relpath(path, root)))
    return files


def build(out_path, legacy=False):
    with open(os.path.join(ADDON, MANIFEST), "rb") as f:
        manifest = tomllib.load(f)
    check_manifest(manifest, legacy_bl_info(os.path.join(ADDON, "__init__.py")))
    files = packaged_files(ADDON)
    # A legacy install unpacks the zip into the add-ons folder: the package is its folder.
    prefix = os.path.basename(ADDON) + "/" if legacy else ""
    with zipfile.ZipFile(out_path, "w", zipfile.ZIP_DEFLATED) as archive:
        for path, name in files:
            archive.write(path, prefix + name)
    return manifest, len(files)


def main():
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--legacy", action="store_true", help="the legacy add-on zip for Blender 3.4 to 4.1")
    parser.add_argument("-o", "--output", help="the zip to write")
    args = parser.parse_args()
    output = args.output or os.path.join(HERE, "lensblur.zip" if args.legacy else "lensblur-extension.zip")
    manifest, count = build(output, args.legacy)
    kind = "legacy add-on, Blender 3.4+" if args.legacy else f"Extension, Blender {manifest['blender_version_min']}+"
    print(f"{output}: {manifest['id']} {manifest['version']} ({kind}), {count} files")


if __name__ == "__main__":
    sys.exit(main())
