"""A cached kernel's library rebuilt from its machine code alone: :func:`object_code_only`, used by
:class:`pdr.filters.compiled.LeanFunctionCache`.

numba caches a kernel as two parts: the machine code (an ELF object) that runs, and the whole LLVM module of the
kernel and of every kernel it calls (bitcode), kept so that a kernel compiled later can link it in and inline it. When
it loads a kernel, numba parses that bitcode (``llvmlite.binding.parse_bitcode``) and walks every function and global
of the module for the names it defines, which the execution engine looks its entry points up by. A ``pdr track``
process compiles nothing: of its 19 loads' 1.7 MB of bitcode it only needs the names, and those are in the object's
own symbol table. Measured in a ``pdr track`` process on a one-hour log (numba's ``_unserialize`` timed part by
part, three runs): parsing the bitcode 70-115 ms and the walk 14-22 ms of the 110-150 ms the loads took; reading the
names from the ELF symbol tables about 2 ms. On every kernel of that process the two sets of names are the same (835
for the attitude kernel).

So a library is rebuilt here with the object code as numba does, its defined names read from the ELF symbol table
(:func:`elf_defined_symbols`), and the bitcode kept unparsed: the library parses it the first time a kernel being
compiled links it in (:meth:`_LazyLinking._get_module_for_linking`), so that compiling still inlines it as before.
The machine code that runs is the same bytes, so every result is bit for bit the same. An object that is not a
64-bit little-endian ELF (macOS, Windows), or a library numba cached as bitcode, is rebuilt by numba's own code,
and so is every library when numba's internals named here are not there (a later numba).
"""

from __future__ import annotations

import struct
from collections.abc import Iterator
from contextlib import contextmanager
from typing import Any

import llvmlite.binding as ll

#: ELF section type of a symbol table, and the symbol types numba's module walk counts (data objects, functions).
_SHT_SYMTAB = 2
_STT_OBJECT, _STT_FUNC = 1, 2
_SHN_UNDEF = 0


def elf_defined_symbols(obj: bytes) -> set[str] | None:
    """Names of the functions and data objects that the 64-bit little-endian ELF object ``obj`` defines (its symbol
    table's entries with a section), or None when ``obj`` is not such an object.
    """
    if len(obj) < 64 or obj[:4] != b"\x7fELF" or obj[4] != 2 or obj[5] != 1:
        return None
    (shoff,) = struct.unpack_from("<Q", obj, 0x28)
    shentsize, shnum = struct.unpack_from("<HH", obj, 0x3A)
    # Section header: name, type, flags, addr, offset, size, link, info, addralign, entsize.
    sections = [struct.unpack_from("<IIQQQQIIQQ", obj, shoff + i * shentsize) for i in range(shnum)]
    names: set[str] = set()
    for _, kind, _, _, offset, size, link, _, _, entsize in sections:
        if kind != _SHT_SYMTAB or entsize == 0:
            continue
        strings = sections[link][4]
        for entry in range(offset + entsize, offset + size, entsize):      # entry 0 is the null symbol
            name, info, _, section = struct.unpack_from("<IBBH", obj, entry)
            if section != _SHN_UNDEF and info & 0xF in (_STT_OBJECT, _STT_FUNC):
                at = strings + name
                names.add(obj[at:obj.index(b"\0", at)].decode("utf-8"))
    return names


class _LazyLinking:
    """Mixed into numba's library class: the module for linking is parsed from the kept bitcode on first use."""

    _shared_bitcode: bytes | None = None
    _shared_module: Any

    def _get_module_for_linking(self) -> Any:
        if self._shared_module is None and self._shared_bitcode is not None:
            self._shared_module = ll.parse_bitcode(self._shared_bitcode)
            self._shared_bitcode = None
        return super()._get_module_for_linking()  # type: ignore[misc]


_LAZY_CLASSES: dict[type, type] = {}


def _lazy_class(base: type) -> type:
    """``base`` (numba's library class of a codegen) with :class:`_LazyLinking` mixed in (made once per class)."""
    cls = _LAZY_CLASSES.get(base)
    if cls is None:
        cls = _LAZY_CLASSES[base] = type(f"Lazy{base.__name__}", (_LazyLinking, base), {})
    return cls


def unserialize(codegen: Any, state: tuple[str, str, Any]) -> Any:
    """The library of numba's serialized ``state`` (name, kind, data) on ``codegen``: from its object code and ELF
    names (module doc), as numba's ``CPUCodeLibrary._unserialize`` otherwise does it.
    """
    name, kind, data = state
    symbols = elf_defined_symbols(data[0]) if kind == "object" else None
    if symbols is None:
        return codegen._library_class._unserialize(codegen, state)
    object_code, shared_bitcode = data
    try:
        library = _lazy_class(codegen._library_class)(codegen, name)
        library.enable_object_caching()
        library._set_compiled_object(object_code)
        library._shared_bitcode = shared_bitcode
        library._finalize_final_module()    # the engine takes the object code through numba's object cache hook
        engine_symbols = codegen._engine._defined_symbols
    except (AttributeError, TypeError):
        # A numba whose internals moved (these are not its public API): its own, slower rebuild.
        return codegen._library_class._unserialize(codegen, state)
    engine_symbols |= symbols
    return library


@contextmanager
def object_code_only(codegen: Any) -> Iterator[None]:
    """Libraries that ``codegen`` unserializes inside the block are rebuilt by :func:`unserialize`.

    For numba's cache loads, which run under numba's global compiler lock: nothing else unserializes meanwhile.
    """
    codegen.unserialize_library = lambda state: unserialize(codegen, state)
    try:
        yield
    finally:
        del codegen.unserialize_library
