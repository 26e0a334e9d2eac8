"""Node type registry: built-ins, installed packages and plugin folders, found one way.

Every source of node types is a Python module; every :class:`~flowtex.node_api.Node`
subclass with a ``type_name`` defined in it is registered.

* Built-in nodes: :data:`BUILTIN_TYPES`, name -> ``"module:Class"``, imported on
  first use (as python-can's ``BACKENDS``): listing the names, or resolving a graph
  that uses only filters, imports no other node module.
* Installed packages: entry points of group ``flowtex.nodes``
  (an entry point may name a module, a package -- all its public submodules --
  or a single Node class). flowtex's own entry point names ``flowtex.nodes``: the
  built-in table. They are lazy too: an entry point's name is listed as a node type
  (``flowtex plugin new`` names it after its node type) and its ``value`` is imported
  on the first use of that name, or of a name nothing else defines (a package may
  define types under other names), or when every type is listed in full
  (:meth:`Registry.load_all`). An entry point that fails to import is reported,
  naming it, where it is first used.
* Plugin folders: every ``*.py`` file in each folder of ``FLOWTEX_PLUGINS``
  (``os.pathsep``-separated), in each ``--plugins DIR``, and (added by the graph
  loader) in the graph file's own ``plugins/`` folder and the folders its
  ``plugins:`` key names. The current working directory is never searched: a
  folder a user happens to run flowtex in is not code they chose to run.
"""

from __future__ import annotations

import hashlib
import importlib
import importlib.util
import inspect
import os
import pkgutil
import sys
from collections.abc import Callable, Iterable, Iterator, Mapping
from importlib.metadata import EntryPoint, entry_points
from pathlib import Path
from types import ModuleType

from .config import PLUGIN_ENV, plugin_folders
from .errors import FlowtexError
from .node_api import Node
from .nodecheck import check_node_class, error_line, shown_path, type_name_location
from .plugincode import PLUGIN_CODE, plugin_code_id, register_plugin_package

ENTRY_POINT_GROUP = "flowtex.nodes"
__all__ = ["BUILTIN_PACKAGE", "BUILTIN_TYPES", "ENTRY_POINT_GROUP", "PLUGIN_ENV", "NodeTypes", "Registry", "load_plugin_file",
           "load_registry", "plugin_dirs"]

# The built-in package, used when flowtex runs from a source tree without
# installed metadata; the installed entry point names the same package.
BUILTIN_PACKAGE = "flowtex.nodes"

BUILTIN_TYPES: dict[str, str] = {
    "constant": "flowtex.nodes.arith:Constant",
    "gain": "flowtex.nodes.arith:Gain",
    "add": "flowtex.nodes.arith:Add",
    "subtract": "flowtex.nodes.arith:Subtract",
    "multiply": "flowtex.nodes.arith:Multiply",
    "clip": "flowtex.nodes.arith:Clip",
    "norm": "flowtex.nodes.arith:Norm",
    "select": "flowtex.nodes.arith:Select",
    "compliance_estimator": "flowtex.nodes.compliance:ComplianceEstimator",
    "delay": "flowtex.nodes.delay:Delay",
    "dft321": "flowtex.nodes.dft321:Dft321",
    "biquad": "flowtex.nodes.filters:Biquad",
    "butterworth": "flowtex.nodes.filters:Butterworth",
    "first_order_lowpass": "flowtex.nodes.filters:FirstOrderLowpass",
    "differentiator": "flowtex.nodes.filters:Differentiator",
    "coulomb_friction": "flowtex.nodes.friction:CoulombFriction",
    "dahl_friction": "flowtex.nodes.friction:DahlFriction",
    "speed_estimator": "flowtex.nodes.motion:SpeedEstimator",
    "contact": "flowtex.nodes.motion:Contact",
    "white_noise": "flowtex.nodes.noise:WhiteNoise",
    "patterned_texture": "flowtex.nodes.patterns:PatternedTexture",
    "resample": "flowtex.nodes.resample:Resample",
    "surface_switch": "flowtex.nodes.switch:SurfaceSwitch",
    "arma_synth": "flowtex.nodes.synthesis:ArmaSynth",
    "tap_player": "flowtex.nodes.taps:TapPlayer",
    "texture_lookup": "flowtex.nodes.texture:TextureLookup",
    "cross": "flowtex.nodes.vector:Cross",
    "dot": "flowtex.nodes.vector:Dot",
    "normalize": "flowtex.nodes.vector:Normalize",
}
"""Every built-in node type: name -> ``"module:Class"``, imported on first use (tests/test_registry_lazy.py keeps this
table equal to the node types the modules of :data:`BUILTIN_PACKAGE` define)."""


class NodeTypes(Mapping[str, type[Node]]):
    """Node type name -> class; a lazily registered entry is imported and checked on first access.

    A lazy entry is a built-in's ``"module:Class"`` or an entry point's loader (a callable that registers what
    the entry point defines). Names, ``in`` and ``len`` import nothing; ``types[name]``, ``values()`` and
    ``items()`` import what they return. A loader that defines no type of its own name (a package's entry point)
    drops the name: ``types[name]`` then raises KeyError, as for an unknown name.
    """

    def __init__(self) -> None:
        self._classes: dict[str, type[Node]] = {}
        self._lazy: dict[str, str | Callable[[], None]] = {}
        self._order: dict[str, None] = {}

    def set(self, name: str, cls: type[Node]) -> None:
        self._classes[name] = cls
        self._lazy.pop(name, None)
        self._order.setdefault(name, None)

    def set_lazy(self, name: str, target: str | Callable[[], None]) -> None:
        self._lazy[name] = target
        self._order.setdefault(name, None)

    def __getitem__(self, name: str) -> type[Node]:
        if name in self._classes:
            return self._classes[name]
        target = self._lazy[name]  # KeyError for an unknown name, as a dict
        if callable(target):
            del self._lazy[name]
            try:
                target()
            except BaseException:
                self._lazy[name] = target  # the same clear error at the next use
                raise
            if name in self._classes:
                return self._classes[name]
            self._order.pop(name, None)
            raise KeyError(name)
        module_name, _, attr = target.partition(":")
        cls = getattr(importlib.import_module(module_name), attr, None)
        if not (inspect.isclass(cls) and issubclass(cls, Node) and cls.type_name == name):
            raise FlowtexError(f"node type {name!r}: {target} is not its Node class (flowtex.registry.BUILTIN_TYPES is out of date)")
        check_node_class(cls)
        self.set(name, cls)
        return cls

    def __contains__(self, name: object) -> bool:
        return name in self._order

    def __iter__(self) -> Iterator[str]:
        return iter(list(self._order))

    def __len__(self) -> int:
        return len(self._order)


class Registry:
    """A name -> Node class table with the origin of each entry."""

    def __init__(self) -> None:
        self.types = NodeTypes()
        self.origins: dict[str, str] = {}
        self.plugin_files: list[Path] = []
        """Plugin files (Python code) imported into this registry, in load order."""
        self._pending: dict[str, EntryPoint] = {}
        """Installed entry points not imported yet, by name."""

    def add_module(self, module: ModuleType, origin: str) -> None:
        for obj in vars(module).values():
            if inspect.isclass(obj) and issubclass(obj, Node) and obj.type_name and obj.__module__ == module.__name__:
                self.add(obj, origin)

    def add(self, cls: type[Node], origin: str) -> None:
        """Register ``cls``; its kernel is checked against the node contract first (errors name its file and line)."""
        name = cls.type_name
        check_node_class(cls)
        try:
            existing = self.types[name] if name in self.types else None
        except KeyError:  # the name of an entry point being loaded, or of one that defines no such type
            existing = None
        if existing is not None and existing is not cls:
            where = type_name_location(cls)
            raise FlowtexError(f"{where or origin}: node type {name!r} is already defined by {self.origins[name]}; "
                               f"rename one of them{' (flowtex nodes lists the taken names)' if where else ''}")
        self.types.set(name, cls)
        self.origins[name] = origin

    def add_lazy(self, name: str, target: str, origin: str) -> None:
        """Register the built-in ``name`` as ``"module:Class"``, imported (and checked) when first used."""
        self.types.set_lazy(name, target)
        self.origins[name] = origin

    def add_entry_point(self, ep: EntryPoint) -> None:
        """Register an installed entry point lazily: its name now, its ``value`` imported when first needed."""
        self._pending[ep.name] = ep
        if ep.name not in self.types:  # a name taken already is checked when the entry point loads
            self.types.set_lazy(ep.name, lambda: self._load_entry_point(ep.name))
            self.origins[ep.name] = f"entry point {ep.value}"

    def _load_entry_point(self, name: str) -> None:
        ep = self._pending.pop(name, None)
        if ep is None:
            return
        register_plugin_package(ep.module)  # its kernels' compiled code is keyed by its package's sources
        try:
            obj = ep.load()
        except Exception as exc:
            self._pending[name] = ep
            raise FlowtexError(f"entry point {ep.name!r} ({ep.value}) of group {ENTRY_POINT_GROUP} failed to load: "
                               f"{type(exc).__name__}: {exc}; fix or uninstall the package that provides it") from exc
        if isinstance(obj, ModuleType):
            for module in _with_submodules(obj):
                self.add_module(module, f"entry point {ep.value}")
        elif inspect.isclass(obj) and issubclass(obj, Node):
            self.add(obj, f"entry point {ep.value}")
        else:
            raise FlowtexError(f"entry point {ep.name!r} ({ep.value}) is neither a module nor a Node class")

    def load_all(self) -> None:
        """Import every installed entry point not imported yet (a full listing describes every type)."""
        for name in list(self._pending):
            if name in self.types:
                try:
                    self.types[name]
                except KeyError:  # a package's entry point: its types have other names
                    pass
            self._load_entry_point(name)

    def get(self, name: str) -> type[Node] | None:
        """The class of node type ``name``; None if nothing defines it (pending entry points are imported first)."""
        if name in self.types:
            try:
                return self.types[name]
            except KeyError:
                pass
        if self._pending:
            self.load_all()
            return self.get(name)
        return None

    def __contains__(self, name: str) -> bool:
        return name in self.types

    def names(self) -> list[str]:
        return sorted(self.types)


def folder_list(folders: Iterable[str | Path] | str | Path) -> tuple[str | Path, ...]:
    """``folders`` as a tuple of folders; one folder given as a string or path is one folder, not its characters."""
    return (folders,) if isinstance(folders, (str, os.PathLike)) else tuple(folders)  # type: ignore[return-value]


def plugin_dirs(extra: Iterable[str | Path] = ()) -> list[Path]:
    """Plugin folders in search order: ``$FLOWTEX_PLUGINS``, then ``extra``."""
    dirs: list[Path] = []
    dirs.extend(plugin_folders())
    dirs.extend(Path(d) for d in folder_list(extra))
    unique: list[Path] = []
    for d in dirs:
        resolved = d.resolve()
        if resolved not in unique:
            unique.append(resolved)
    return unique


def _plugin_module_name(path: Path) -> tuple[str, str | None]:
    """The private module name of plugin file ``path``, and its code id (None: filed by its path, as numba does).

    The name comes from the file's stem and its folder's sources (:func:`flowtex.plugincode.plugin_code_id`), since
    numba's cached code names the module it was compiled in: a copy of the folder in another place then loads the code
    compiled for the first. A second copy loaded in the same process runs as a module of its own (its ``__file__`` and
    the data beside it are its own), named and cached by its path.
    """
    code = plugin_code_id(path)
    name = f"{_PLUGIN_MODULE_PREFIX}{path.stem}_{code}"
    loaded = sys.modules.get(name)
    if loaded is None or Path(getattr(loaded, "__file__", "")).resolve() == path.resolve():
        return name, code
    return f"{_PLUGIN_MODULE_PREFIX}{path.stem}_{hashlib.sha1(str(path.resolve()).encode()).hexdigest()[:10]}", None


def load_plugin_file(path: Path) -> ModuleType:
    """Import one plugin file under a stable private module name (:func:`_plugin_module_name`)."""
    mod_name, code = _plugin_module_name(path)
    if mod_name in sys.modules:
        return sys.modules[mod_name]
    spec = importlib.util.spec_from_file_location(mod_name, path)
    if spec is None or spec.loader is None:
        raise FlowtexError(f"{path}: cannot load plugin file")
    module = importlib.util.module_from_spec(spec)
    if code is not None:
        setattr(module, PLUGIN_CODE, code)  # its compiled code is filed by its folder's sources (flowtex.cache)
    sys.modules[mod_name] = module
    try:
        spec.loader.exec_module(module)
    except FlowtexError:
        del sys.modules[mod_name]
        raise
    except SystemExit as exc:  # sys.exit() in a plugin would end any command "successfully" with nothing done
        del sys.modules[mod_name]
        line = error_line(exc, path)
        raise FlowtexError(f"{shown_path(path)}:{line}: plugin called sys.exit({exc.code!r}) while being imported; a plugin file "
                           "must only define node types (flowtex stopped, nothing done)") from None
    except Exception as exc:  # a plugin's own bug: report it as the plugin's error
        del sys.modules[mod_name]
        line = error_line(exc, path)
        raise FlowtexError(f"{shown_path(path)}:{line}: plugin failed to load: {type(exc).__name__}: {exc}") from exc
    return module


def _with_submodules(module: ModuleType) -> list[ModuleType]:
    """A module, or a package with all its public submodules (one level)."""
    found = [module]
    if hasattr(module, "__path__"):
        for info in sorted(pkgutil.iter_modules(module.__path__), key=lambda m: m.name):
            if not info.name.startswith("_"):
                found.append(importlib.import_module(f"{module.__name__}.{info.name}"))
    return found


_CACHE: dict[tuple[Path, ...], Registry] = {}
_PLUGIN_MODULE_PREFIX = "flowtex_plugin_"


def forget_plugin_code() -> None:
    """Forget every loaded plugin file and registry, so the next :func:`load_registry` imports edited plugins afresh."""
    _CACHE.clear()
    for name in [n for n in sys.modules if n.startswith(_PLUGIN_MODULE_PREFIX)]:
        del sys.modules[name]


def load_registry(plugins: Iterable[str | Path] = ()) -> Registry:
    """Registry with built-ins, installed entry points, ``$FLOWTEX_PLUGINS`` and the plugin folders ``plugins``."""
    dirs = tuple(plugin_dirs(plugins))
    if dirs in _CACHE:
        return _CACHE[dirs]
    reg = Registry()
    found = sorted(entry_points(group=ENTRY_POINT_GROUP), key=lambda e: e.name)
    installed = any(ep.value == BUILTIN_PACKAGE for ep in found)
    for name, target in BUILTIN_TYPES.items():
        reg.add_lazy(name, target, f"entry point {BUILTIN_PACKAGE}" if installed else target.partition(":")[0])
    for ep in found:
        if ep.value != BUILTIN_PACKAGE:  # flowtex's own is the lazy table above
            reg.add_entry_point(ep)
    for folder in dirs:
        if not folder.is_dir():
            raise FlowtexError(f"{folder}: plugin folder does not exist")
        for path in sorted(folder.glob("*.py")):
            reg.add_module(load_plugin_file(path), str(path))
            reg.plugin_files.append(path)
    _CACHE[dirs] = reg
    return reg
