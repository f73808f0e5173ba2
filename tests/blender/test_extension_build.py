# SPDX-License-Identifier: GPL-3.0-or-later
"""A real extension: the zip built by scripts/build.py validates, installs, renders, uninstalls;
the Add-menu operator, the bundled asset library and the layer groups it ships (a first Make
Hazy of the installed copy builds nothing).

The zip is built once per session (``built_zip``) by running ``scripts/build.py`` in a
subprocess with ``.venv/bin/python`` when it exists — the documented build command, so under
.venv45 the 4.5 tests install the very zip that is shipped (built by bpy 5.0) — else with this
interpreter.
The installed copy lives in its own repository ``hg_install_test``, i.e. it loads as
``bl_ext.hg_install_test.hazy_gloss``; the session's ``bl_ext.test_repo.hazy_gloss`` is disabled
while the installed copy is enabled (both register the same class names) and re-enabled after.
"""
from __future__ import annotations

import importlib
import os
import shutil
import stat
import subprocess
import sys
import tomllib
import zipfile
from pathlib import Path

import addon_utils
import bpy
import numpy as np
import pytest

REPO_ROOT = Path(__file__).resolve().parents[2]
PACKAGE_DIR = REPO_ROOT / "hazy_gloss"
BUILD_SCRIPT = REPO_ROOT / "scripts" / "build.py"
ADDON_ID = "hazy_gloss"
INSTALL_REPO = "hg_install_test"
INSTALLED_MODULE = f"bl_ext.{INSTALL_REPO}.{ADDON_ID}"
ASSET_BLEND = "assets/hazy_gloss_nodes.blend"
LAYER_GROUPS = "layer_groups"
CATALOGS = "assets/blender_assets.cats.txt"

EXCLUDED_PARTS = ("tests", "docs", "benchmarks", "__pycache__", ".pytest_cache", ".hypothesis",
                  ".git", "dist", "out")
BLENDER_45_ID_NAME_BYTES = 63  # MAX_ID_NAME - 3 before 5.0


def _manifest():
    with open(REPO_ROOT / "blender_manifest.toml", "rb") as fh:
        return tomllib.load(fh)


@pytest.fixture(scope="session")
def built_zip(tmp_path_factory):
    """Run ``scripts/build.py --output-dir <tmp>`` once; return the zip's path."""
    out = tmp_path_factory.mktemp("dist")
    env = dict(os.environ)
    env.pop("PYTHONPATH", None)
    env["BLENDER_USER_RESOURCES"] = str(tmp_path_factory.mktemp("build_user_resources"))
    python = REPO_ROOT / ".venv" / "bin" / "python"
    python = str(python) if python.exists() else sys.executable
    proc = subprocess.run([python, str(BUILD_SCRIPT), "--output-dir", str(out)],
                          cwd=str(REPO_ROOT), env=env, capture_output=True, text=True, timeout=300)
    assert proc.returncode == 0, (f"build.py exited {proc.returncode}\n--- stdout ---\n"
                                  f"{proc.stdout[-4000:]}\n--- stderr ---\n{proc.stderr[-4000:]}")
    manifest = _manifest()
    path = out / f"{manifest['id']}-{manifest['version']}.zip"
    assert path.is_file(), f"{path} missing; build output:\n{proc.stdout[-2000:]}"
    assert "Success parsing TOML" in proc.stdout  # bl_pkg validate ran on the zip
    return path


@pytest.fixture(scope="session")
def zip_names(built_zip):
    with zipfile.ZipFile(built_zip) as zf:
        return {i.filename: i for i in zf.infolist()}


def _source_files():
    """Files the package ships, relative to it, plus the top-level manifest."""
    files = {"blender_manifest.toml"}
    for root, dirs, names in os.walk(PACKAGE_DIR, followlinks=True):
        dirs[:] = [d for d in dirs
                   if d not in EXCLUDED_PARTS and d not in ("assets", "layer_groups")]
        for n in names:
            if n.endswith((".pyc", ".pyo")):
                continue
            files.add(Path(root, n).relative_to(PACKAGE_DIR).as_posix())
    return files


# ------------------------------------------------------------------------------------------------
# The zip
# ------------------------------------------------------------------------------------------------


def test_zip_validates_with_bl_pkg(built_zip, capsys):
    import bl_pkg
    assert bl_pkg.cli_extension(["validate", str(built_zip)]) == 0
    assert "Success parsing TOML" in capsys.readouterr().out


def test_manifest_requirements(zip_names, built_zip):
    with zipfile.ZipFile(built_zip) as zf:
        manifest = tomllib.loads(zf.read("blender_manifest.toml").decode("utf-8"))
    assert manifest["schema_version"] == "1.0.0"
    assert manifest["id"] == ADDON_ID
    assert manifest["type"] == "add-on"
    assert manifest["blender_version_min"] == "4.5.0"
    assert manifest["license"] == ["SPDX:GPL-3.0-or-later"]
    from _bpy_internal.extensions import tags as blender_tags
    assert manifest["tags"] and set(manifest["tags"]) <= blender_tags.addons
    assert set(manifest["permissions"]) == {"files"}
    assert isinstance(manifest["permissions"]["files"], str) and manifest["permissions"]["files"]
    assert len(manifest["tagline"]) <= 64 and manifest["tagline"][-1].isalnum()


def test_zip_holds_real_files_and_nothing_excluded(zip_names, built_zip):
    names = {n for n in zip_names if not n.endswith("/")}
    for name, info in zip_names.items():
        parts = name.rstrip("/").split("/")
        assert not set(parts) & set(EXCLUDED_PARTS), f"excluded path shipped: {name}"
        assert not name.endswith((".pyc", ".pyo", ".blend1")), name
        assert not stat.S_ISLNK(info.external_attr >> 16), f"symlink in zip: {name}"
    # Exactly the package's files plus the manifest and the generated assets.
    shipped = {n for n in names if n.startswith(LAYER_GROUPS + "/")}
    assert names == _source_files() | {ASSET_BLEND, CATALOGS} | shipped
    with zipfile.ZipFile(built_zip) as zf:
        assert zf.read("blender_manifest.toml") == (REPO_ROOT / "blender_manifest.toml").read_bytes()
        for py in PACKAGE_DIR.rglob("*.py"):
            if "__pycache__" not in py.parts:
                assert zf.read(py.relative_to(PACKAGE_DIR).as_posix()) == py.read_bytes(), py
        assert zf.getinfo(ASSET_BLEND).file_size > 10_000


def _shipped_files(layer_group, version):
    """The files of layer_group.SHIPPED built by Blender ``version`` ("5.3"), as the zip names
    them (the group name ends with the version that built it, in its brackets)."""
    here = layer_group.version_tag()
    out = set()
    for kind, settings, parts in layer_group.SHIPPED:
        name = layer_group.group_name(kind, settings, parts=parts)
        assert name.endswith(f" {here})")
        out.add(f"{LAYER_GROUPS}/" + layer_group._file_name(f"{name[:-len(here) - 1]}{version})"))
    return out


def test_zip_ships_the_layer_groups(zip_names, hg):
    """Every Blender the build found ships all of layer_group.SHIPPED (this session's Blender
    among them: the build here has the venvs of all three), named as the per-user cache names
    them; nothing else is in layer_groups/."""
    layer_group = importlib.import_module(hg.__name__ + ".blender.model.layer_group")
    shipped = {n for n in zip_names if n.startswith(LAYER_GROUPS + "/")}
    versions = {n[:-len(".blend")].rsplit("_", 1)[1] for n in shipped}
    assert layer_group.version_tag() in versions, sorted(versions)
    for version in versions:
        want = _shipped_files(layer_group, version)
        assert want <= shipped, f"bpy {version}: missing {sorted(want - shipped)}"
        shipped -= want
    assert not shipped, f"unexpected layer groups: {sorted(shipped)}"


def _expected_groups(groups_mod):
    return {groups_mod.group_name(*c): c for c in groups_mod.all_configurations()}


def test_group_names_fit_blender_45_id_limit(hg):
    """Blender 4.5 truncates ID names to 63 bytes, so ensure_group() cannot find (and rebuilds)
    a group with a longer name, and 4.5 drops such groups when reading a 5.0 asset file."""
    groups = importlib.import_module(hg.__name__ + ".blender.model.groups")
    long = [n for n in _expected_groups(groups) if len(n.encode()) > BLENDER_45_ID_NAME_BYTES]
    assert not long, f"names over {BLENDER_45_ID_NAME_BYTES} bytes: {long}"


def test_asset_library_blend(clean_file, hg, built_zip, tmp_path):
    """Every node group is in the .blend, marked as an asset with a description and a catalog
    defined in blender_assets.cats.txt."""
    groups = importlib.import_module(hg.__name__ + ".blender.model.groups")
    menus = importlib.import_module(hg.__name__ + ".blender.ui.menus")
    with zipfile.ZipFile(built_zip) as zf:
        zf.extract(ASSET_BLEND, tmp_path)
        cats = zf.read(CATALOGS).decode("utf-8")
    catalog_ids = {line.split(":")[0]: line.split(":")[1] for line in cats.splitlines()
                   if line and not line.startswith(("#", "VERSION"))}
    assert set(catalog_ids.values()) == {"Hazy Gloss", "Hazy Gloss/Conductor",
                                         "Hazy Gloss/Dielectric", "Hazy Gloss/Legacy"}
    expected = _expected_groups(groups)
    path = str(tmp_path / ASSET_BLEND)
    with bpy.data.libraries.load(path, link=True, assets_only=True) as (src, dst):
        assert set(expected) <= set(src.node_groups)
        dst.node_groups = sorted(expected)
    for ng in dst.node_groups:
        kind, dist, aniso, smooth = expected[ng.name]
        assert ng.asset_data is not None, ng.name
        assert ng.asset_data.description == menus.describe(kind, dist, aniso, smooth)
        assert catalog_ids[ng.asset_data.catalog_id] == f"Hazy Gloss/{menus.KIND_LABELS[kind]}"
        stamp = ng[importlib.import_module(hg.__name__ + ".constants").GROUP_STAMP]
        assert (stamp["kind"], stamp["distribution"], bool(stamp["anisotropic"]),
                bool(stamp["smooth"])) == (kind, dist, aniso, smooth)
        assert stamp["version"] == groups.GROUP_VERSION
        assert any(n.bl_idname == "NodeGroupOutput" for n in ng.nodes)


# ------------------------------------------------------------------------------------------------
# Install, enable, render, disable, uninstall
# ------------------------------------------------------------------------------------------------


def _repo(module):
    return next((r for r in bpy.context.preferences.extensions.repos if r.module == module), None)


def _installed_state():
    loaded_default, loaded_state = addon_utils.check(INSTALLED_MODULE)
    return {"enabled": bool(loaded_default and loaded_state),
            "in_prefs": INSTALLED_MODULE in bpy.context.preferences.addons,
            "in_sys_modules": INSTALLED_MODULE in sys.modules}


def _our_libraries(path):
    real = os.path.realpath(path)
    return [lib for lib in bpy.context.preferences.filepaths.asset_libraries
            if os.path.realpath(bpy.path.abspath(lib.path)) == real]


def test_install_enable_render_disable_uninstall(addon_module, built_zip, tmp_path):
    import scenes

    repo_dir = tmp_path / "ext_repo"
    repo_dir.mkdir()
    repos = bpy.context.preferences.extensions.repos
    assert _repo(INSTALL_REPO) is None
    repo = repos.new(name="Hazy Gloss Install Test", module=INSTALL_REPO,
                     custom_directory=str(repo_dir), source="USER")
    installed_dir = repo_dir / ADDON_ID
    assets_dir = installed_dir / "assets"
    try:
        # The session's copy registers the same class names: take it out of the way.
        addon_module.disable()
        assert addon_utils.check(addon_module.name)[1] is False
        assert not hasattr(bpy.types, "HAZY_GLOSS_OT_add_node")

        # -- install (returns FINISHED even on failure: check the real state) ------------------
        result = bpy.ops.extensions.package_install_files(
            filepath=str(built_zip), repo=INSTALL_REPO, enable_on_install=True)
        assert result == {"FINISHED"}
        assert installed_dir.is_dir(), f"nothing installed in {repo_dir}: {os.listdir(repo_dir)}"
        on_disk = {p.relative_to(installed_dir).as_posix() for p in installed_dir.rglob("*")
                   if p.is_file() and "__pycache__" not in p.parts}
        with zipfile.ZipFile(built_zip) as zf:
            assert on_disk == {n for n in zf.namelist() if not n.endswith("/")}
        assert not any(p.is_symlink() for p in installed_dir.rglob("*"))

        # -- enabled, importable, registered ----------------------------------------------------
        assert _installed_state() == {"enabled": True, "in_prefs": True, "in_sys_modules": True}
        mod = importlib.import_module(INSTALLED_MODULE)
        assert Path(mod.__file__).resolve().parent == installed_dir.resolve()
        info = addon_utils.module_bl_info(mod)
        assert info["name"] == _manifest()["name"]
        api = importlib.import_module(INSTALLED_MODULE + ".api")
        assert Path(api.__file__).resolve().is_relative_to(installed_dir.resolve())
        assert hasattr(bpy.types, "HAZY_GLOSS_OT_add_node")
        assert hasattr(bpy.types, "HAZY_GLOSS_MT_add")
        libs = _our_libraries(assets_dir)
        assert len(libs) == 1 and libs[0].name == "Hazy Gloss"
        default = bpy.types.UserAssetLibrary.bl_rna.properties["import_method"].default
        assert libs[0].import_method == default  # APPEND_REUSE in 4.5, PACK in 5.0

        # -- a hazy material renders -----------------------------------------------------------
        bpy.ops.wm.read_homefile(use_empty=True)
        assert _installed_state()["enabled"]
        scenes.setup_render(samples=1, resolution=(8, 8), bounces=0)
        mat = api.create_material("Installed Hazy", kind="CONDUCTOR",
                                  core_reflectivity=(0.9, 0.6, 0.3), edge_tint=(1.0, 0.8, 0.5),
                                  roughness=0.3, haziness=0.8, haze_extent=5.0)
        assert api.is_hazy(mat)
        scenes.flat_plane_scene(mat, light_dir=(10.0, 0.0), strength=3.0)
        img = scenes.render_exr()
        rgb = img[..., :3]
        assert np.isfinite(rgb).all()
        assert float(rgb.max()) > 0.0, "the hazy plane rendered black"
        # The operator of the installed copy works too.
        assert bpy.ops.hazy_gloss.add_node(kind="LEGACY", distribution="GGX",
                                           material=mat.name) == {"FINISHED"}
        assert any(n.bl_idname == "ShaderNodeGroup" for n in mat.node_tree.nodes)

        # -- the first Make Hazy on this machine appends the shipped group: nothing is built --
        layer_group = importlib.import_module(INSTALLED_MODULE + ".blender.model.layer_group")
        plain = importlib.import_module(INSTALLED_MODULE + ".blender.compat").new_material("Plain")
        core = next(n for n in plain.node_tree.nodes if n.bl_idname == "ShaderNodeBsdfPrincipled")
        shipped = layer_group._shipped_path(layer_group.group_name(
            "PRINCIPLED", layer_group.settings_of(core), parts=("dielectric",)))
        assert Path(shipped).is_file() and Path(shipped).is_relative_to(installed_dir)

        assert not any(layer_group.is_layer_group(g) for g in bpy.data.node_groups)

        def no_build(*_args, **_kw):
            raise AssertionError("built a layer group the extension ships")
        saved = layer_group.build, layer_group._cache_path
        layer_group.build, layer_group._cache_path = no_build, (lambda _name: None)
        try:
            assert list(api.make_hazy(plain, haziness=0.5)) == []
        finally:
            layer_group.build, layer_group._cache_path = saved
        node = next(n for n in plain.node_tree.nodes if n.bl_idname == "ShaderNodeGroup")
        assert layer_group.is_layer_group(node.node_tree) and node.node_tree.library is None
        # appended, not linked: the file does not depend on the extension's files
        assert not [i.name for c in (bpy.data.node_groups, bpy.data.images) for i in c
                    if i.library is not None]

        # -- disable ---------------------------------------------------------------------------
        addon_utils.disable(INSTALLED_MODULE, default_set=True)
        state = _installed_state()
        assert not state["enabled"] and not state["in_prefs"]
        assert not hasattr(bpy.types, "HAZY_GLOSS_OT_add_node")
        assert not hasattr(bpy.types, "HAZY_GLOSS_MT_add")
        assert _our_libraries(assets_dir) == []
        assert installed_dir.is_dir()  # disabled, still installed

        # -- uninstall -------------------------------------------------------------------------
        repo_index = list(repos).index(_repo(INSTALL_REPO))
        result = bpy.ops.extensions.package_uninstall(repo_index=repo_index, pkg_id=ADDON_ID)
        assert result == {"FINISHED"}
        assert not installed_dir.exists(), os.listdir(installed_dir)
        assert not _installed_state()["enabled"]
        assert _our_libraries(assets_dir) == []
    finally:
        if _installed_state()["enabled"]:
            addon_utils.disable(INSTALLED_MODULE, default_set=True)
        for name in [n for n in sys.modules if n == INSTALLED_MODULE
                     or n.startswith(INSTALLED_MODULE + ".")]:
            del sys.modules[name]
        repo = _repo(INSTALL_REPO)
        if repo is not None:
            repos.remove(repo)
        shutil.rmtree(repo_dir, ignore_errors=True)
        bpy.ops.wm.read_homefile(use_empty=True)
        if not all(addon_utils.check(addon_module.name)):
            addon_module.enable()
    assert all(addon_utils.check(addon_module.name))


# ------------------------------------------------------------------------------------------------
# The Add-menu operator and menus (session copy)
# ------------------------------------------------------------------------------------------------


def _new_material(hg, name="Menu Test"):
    compat = importlib.import_module(hg.__name__ + ".blender.compat")
    return compat.new_material(name)


def _group_nodes(mat):
    return [n for n in mat.node_tree.nodes if n.bl_idname == "ShaderNodeGroup"]


@pytest.mark.parametrize("config", [
    ("CONDUCTOR", "GGX", False, False),
    ("DIELECTRIC", "MULTI_GGX", False, True),
    ("LEGACY", "ASHIKHMIN_SHIRLEY", True, False),
    ("CONDUCTOR", "BECKMANN", True, True),
])
def test_add_node_operator(clean_file, hg, config):
    groups = importlib.import_module(hg.__name__ + ".blender.model.groups")
    kind, dist, aniso, smooth = config
    mat = _new_material(hg)
    kw = dict(kind=kind, distribution=dist, anisotropic=aniso, smooth=smooth, material=mat.name)
    assert bpy.ops.hazy_gloss.add_node(**kw) == {"FINISHED"}
    nodes = _group_nodes(mat)
    assert len(nodes) == 1
    node = nodes[0]
    assert node.node_tree.name == groups.group_name(*config)
    stamp = node.node_tree[importlib.import_module(hg.__name__ + ".constants").GROUP_STAMP]
    assert (stamp["kind"], stamp["distribution"], bool(stamp["anisotropic"]),
            bool(stamp["smooth"])) == config
    assert mat.node_tree.nodes.active == node and node.select
    assert node.outputs["BSDF"].type == "SHADER"
    # Adding it again reuses the group.
    count = len(bpy.data.node_groups)
    assert bpy.ops.hazy_gloss.add_node(**kw) == {"FINISHED"}
    assert len(_group_nodes(mat)) == 2 and len(bpy.data.node_groups) == count
    assert {n.node_tree for n in _group_nodes(mat)} == {node.node_tree}


def test_add_node_to_active_object_material(clean_file, hg):
    mat = _new_material(hg, "Active Object Material")
    mesh = bpy.data.meshes.new("M")
    obj = bpy.data.objects.new("O", mesh)
    bpy.context.scene.collection.objects.link(obj)
    mesh.materials.append(mat)
    bpy.context.view_layer.objects.active = obj
    assert bpy.ops.hazy_gloss.add_node(kind="DIELECTRIC", distribution="GGX") == {"FINISHED"}
    assert len(_group_nodes(mat)) == 1


def test_add_node_rejects_bad_requests(clean_file, hg, tmp_path):
    mat = _new_material(hg, "Target")
    with pytest.raises(RuntimeError, match="offer"):  # dielectric lobes have no Beckmann
        bpy.ops.hazy_gloss.add_node(kind="DIELECTRIC", distribution="BECKMANN", material=mat.name)
    with pytest.raises(RuntimeError, match="No material named “no such material”"):
        bpy.ops.hazy_gloss.add_node(material="no such material")
    assert _group_nodes(mat) == []
    # A material linked from a library is read-only.
    lib_mat = _new_material(hg, "Library Material")
    path = str(tmp_path / "lib.blend")
    bpy.data.libraries.write(path, {lib_mat})
    bpy.data.materials.remove(lib_mat)
    with bpy.data.libraries.load(path, link=True) as (src, dst):
        dst.materials = ["Library Material"]
    linked = dst.materials[0]
    assert linked.library is not None
    with pytest.raises(RuntimeError, match="read-only"):
        bpy.ops.hazy_gloss.add_node(material=linked.name)
    assert _group_nodes(linked) == []


class _Props:
    """Operator properties stand-in: only names the operator's RNA defines can be set."""

    def __init__(self, idname):
        mod, name = idname.split(".")
        self._rna = getattr(getattr(bpy.ops, mod), name).get_rna_type()
        object.__setattr__(self, "values", {})

    def __setattr__(self, key, value):
        if key.startswith("_"):
            return object.__setattr__(self, key, value)
        assert key in self._rna.properties, f"{key} is not a property"
        prop = self._rna.properties[key]
        if prop.type == "ENUM":
            assert value in prop.enum_items, f"{key}={value!r}"
        self.values[key] = value


class _Layout:
    """UILayout stand-in for draw functions (background mode never draws menus)."""

    _rna = bpy.types.UILayout.bl_rna

    def __init__(self):
        self.operators, self.menus = [], []
        self.operator_context = "EXEC_REGION_WIN"

    def _check(self, func, kwargs):
        params = self._rna.functions[func].parameters
        for k, v in kwargs.items():
            assert k in params, f"UILayout.{func} has no {k}"
            if k == "icon":
                assert v in params["icon"].enum_items, v

    def operator(self, idname, **kw):
        self._check("operator", kw)
        props = _Props(idname)
        self.operators.append((idname, kw, props))
        return props

    def menu(self, name, **kw):
        self._check("menu", kw)
        assert hasattr(bpy.types, name), f"menu {name} is not registered"
        self.menus.append(name)

    def separator(self, **kw):
        self._check("separator", kw)

    def label(self, **kw):
        self._check("label", kw)


class _Space:
    type = "NODE_EDITOR"

    def __init__(self, tree_type):
        self.tree_type = tree_type


class _Context:
    def __init__(self, tree_type="ShaderNodeTree"):
        self.space_data = _Space(tree_type)


def _draw(menu_cls, context):
    layout = _Layout()
    stand_in = type("Menu", (), {"layout": layout})()
    for attr in ("hazy_kind",):
        if hasattr(menu_cls, attr):
            setattr(stand_in, attr, getattr(menu_cls, attr))
    menu_cls.draw(stand_in, context)
    return layout


def test_add_menu_lists_every_group(hg):
    menus = importlib.import_module(hg.__name__ + ".blender.ui.menus")
    compat = importlib.import_module(hg.__name__ + ".blender.compat")
    groups = importlib.import_module(hg.__name__ + ".blender.model.groups")
    host = compat.shader_add_menu()
    assert host.bl_idname in ("NODE_MT_shader_node_add_all", "NODE_MT_add")
    assert menus.draw_add_menu in host.draw._draw_funcs

    # Our entry in the host menu: one "Hazy Gloss" submenu, shader trees only.
    layout = _Layout()
    menus.draw_add_menu(type("M", (), {"layout": layout})(), _Context())
    assert layout.menus == ["HAZY_GLOSS_MT_add"]
    layout = _Layout()
    menus.draw_add_menu(type("M", (), {"layout": layout})(), _Context("GeometryNodeTree"))
    assert layout.menus == []

    top = _draw(bpy.types.HAZY_GLOSS_MT_add, _Context())
    assert top.menus == [m.bl_idname for m in menus.KIND_MENUS]
    seen = []
    for name in top.menus:
        layout = _draw(getattr(bpy.types, name), _Context())
        for idname, kw, props in layout.operators:
            assert idname == "hazy_gloss.add_node"
            v = props.values
            config = (v["kind"], v["distribution"], v["anisotropic"], v["smooth"])
            assert kw["text"] == groups.group_label(*config[1:])
            assert v["use_transform"] is True
            seen.append(config)
    assert seen == list(groups.all_configurations())


def test_add_menu_removed_on_disable(addon_module, hg):
    host = importlib.import_module(hg.__name__ + ".blender.compat").shader_add_menu()

    def ours():
        return [f for f in host.draw._draw_funcs if getattr(f, "__module__", "").startswith(
            addon_module.name)]

    assert len(ours()) == 1
    try:
        addon_module.disable()
        assert ours() == []
        assert not hasattr(bpy.types, "HAZY_GLOSS_MT_add")
        addon_module.enable()
        assert len(ours()) == 1
    finally:
        if not all(addon_utils.check(addon_module.name)):
            addon_module.enable()


def test_asset_library_registration(hg, tmp_path):
    """register_asset_library adds the folder once (reusing an existing entry) and
    unregister removes it; a folder without the asset file registers nothing."""
    menus = importlib.import_module(hg.__name__ + ".blender.ui.menus")
    libraries = bpy.context.preferences.filepaths.asset_libraries
    before = [(lib.name, lib.path) for lib in libraries]
    # Running from the source checkout: no assets/ folder, nothing registered.
    assert not os.path.exists(menus.asset_directory())
    assert _our_libraries(menus.asset_directory()) == []
    assert menus.register_asset_library(str(tmp_path)) is None

    (tmp_path / menus.ASSET_BLEND).write_bytes(b"")
    lib = menus.register_asset_library(str(tmp_path))
    try:
        assert lib is not None and lib.name == menus.ASSET_LIBRARY_NAME
        assert len(_our_libraries(tmp_path)) == 1
        assert menus.register_asset_library(str(tmp_path)) is not None
        assert len(_our_libraries(tmp_path)) == 1  # reused, not duplicated
    finally:
        menus.unregister_asset_library()
    assert _our_libraries(tmp_path) == []
    assert [(lib.name, lib.path) for lib in libraries] == before
