"""The readers' house plan (issue 15): no import circle through io/, the loader on top of the readers,
the spec helpers other modules use public."""

from __future__ import annotations

import pytest


def _graph():
    grimp = pytest.importorskip("grimp")
    return grimp.build_graph("trainsim", exclude_type_checking_imports=True)


def test_no_import_circle_through_io() -> None:
    graph = _graph()
    io_modules = {m for m in graph.modules if m.startswith("trainsim.io.")} | {"trainsim.io.multipoint_spec"}
    for module in sorted(io_modules):
        # a module reaching itself again through the modules it imports is a circle
        for imported in graph.find_modules_directly_imported_by(module):
            back = graph.find_shortest_chain(importer=imported, imported=module)
            assert back is None, f"{module} -> {imported} -> ... -> {module}: {back}"


def test_only_the_converter_sits_above_the_loader() -> None:
    graph = _graph()
    importers = {
        m
        for m in graph.find_modules_that_directly_import("trainsim.io.loader")
        if m.startswith("trainsim.io.")
    }
    # the converter, and the readers of the system layers' files, which name train and route files
    documents_naming_files = {"trainsim.io.operation_file", "trainsim.io.power_file"}
    assert importers <= {"trainsim.io.convert", *documents_naming_files}, importers


def test_spec_helpers_are_public() -> None:
    from trainsim.io import spec, trainsim_yaml

    assert trainsim_yaml.Spec is spec.Spec and trainsim_yaml.fail is spec.fail
    assert trainsim_yaml.validation_error is spec.validation_error
    # the former private names still work for modules that used them
    assert trainsim_yaml._Spec is spec.Spec and trainsim_yaml._fail is spec.fail
    assert trainsim_yaml._validation_error is spec.validation_error
