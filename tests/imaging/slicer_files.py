"""3D Slicer 5's markups files, as its writer makes them, for the tests.

:func:`slicer_save` imitates what Slicer does when it loads a ``.mrk.json`` and saves the scene
(``vtkSlicerMarkupsLogic::LoadMarkupsFromJson`` then ``vtkMRMLMarkupsJsonStorageNode::
WriteDataInternal``, Slicer main, read for this test): every markup becomes a node (named by the
markup's ``name``, else the file's stem), and every node is saved into its own file
``<node name>.mrk.json``. The writer writes, per markup, only ``type``, ``coordinateSystem``,
``coordinateUnits``, ``locked``, ``fixedNumberOfControlPoints``, ``labelFormat``,
``lastUsedControlPointNumber``, ``controlPoints`` (``id``, ``label``, ``description``,
``associatedNodeID``, ``position``, ``orientation``, ``selected``, ``locked``, ``visibility``,
``positionStatus``), ``measurements`` and ``display``: a markup's ``name``, ``description``
and ``attributes`` are dropped. Positions stay in the coordinate system the file was read in.
"""

from __future__ import annotations

import json
from pathlib import Path
from typing import Any

import jsonschema

SCHEMA_PATH = Path(__file__).parent / "slicer_schema" / "markups-schema-v1.0.3.json"
SLICER_SCHEMA_URL = (
    "https://raw.githubusercontent.com/slicer/slicer/master/Modules/Loadable/Markups/"
    "Resources/Schema/markups-schema-v1.0.3.json#"
)

#: Display properties Slicer 5 writes for a new markup (values as in its defaults).
_DISPLAY = {
    "visibility": True,
    "opacity": 1.0,
    "color": [0.4, 1.0, 1.0],
    "selectedColor": [1.0, 0.5000076295109483, 0.5000076295109483],
    "activeColor": [0.4, 1.0, 0.0],
    "propertiesLabelVisibility": True,
    "pointLabelsVisibility": False,
    "textScale": 3.0,
    "glyphType": "Sphere3D",
    "glyphScale": 1.0,
    "glyphSize": 5.0,
    "useGlyphScale": True,
    "sliceProjection": False,
    "sliceProjectionUseFiducialColor": True,
    "sliceProjectionOutlinedBehindSlicePlane": False,
    "sliceProjectionColor": [1.0, 1.0, 1.0],
    "sliceProjectionOpacity": 0.6,
    "lineThickness": 0.2,
    "lineColorFadingStart": 1.0,
    "lineColorFadingEnd": 10.0,
    "lineColorFadingSaturation": 1.0,
    "lineColorFadingHueOffset": 0.0,
    "handlesInteractive": False,
    "translationHandleVisibility": True,
    "rotationHandleVisibility": True,
    "scaleHandleVisibility": True,
    "interactionHandleScale": 3.0,
    "snapMode": "toVisibleSurface",
}


def validate_markups(doc: Any) -> None:
    """Raise unless ``doc`` validates against Slicer's markups schema v1.0.3."""
    schema = json.loads(SCHEMA_PATH.read_text(encoding="utf-8"))
    jsonschema.Draft7Validator(schema).validate(doc)


def slicer_control_point(
    index: int,
    position: list[float] | None,
    *,
    label: str = "",
    description: str = "",
    status: str = "defined",
) -> dict[str, Any]:
    """A control point exactly as Slicer 5 writes it (LPS orientation of the identity)."""
    return {
        "id": str(index + 1),
        "label": label,
        "description": description,
        "associatedNodeID": "",
        # Slicer writes "" for a point whose position is not defined (preview, undefined).
        "position": position if status == "defined" and position is not None else "",
        "orientation": [-1.0, -0.0, -0.0, -0.0, -1.0, -0.0, 0.0, 0.0, 1.0],
        "selected": True,
        "locked": False,
        "visibility": True,
        "positionStatus": status,
    }


def slicer_markup(
    mtype: str,
    control_points: list[dict[str, Any]],
    *,
    system: str = "LPS",
    units: Any = "mm",
) -> dict[str, Any]:
    """One markup exactly as Slicer 5 writes it (no name, no description)."""
    measurements: list[dict[str, Any]] = []
    if mtype in ("Line", "Curve"):
        measurements = [
            {"name": "length", "enabled": True, "units": "mm", "printFormat": "%-#4.4g%s"}
        ]
    return {
        "type": mtype,
        "coordinateSystem": system,
        "coordinateUnits": units,
        "locked": False,
        "fixedNumberOfControlPoints": False,
        "labelFormat": "%N-%d",
        "lastUsedControlPointNumber": len(control_points),
        "controlPoints": control_points,
        "measurements": measurements,
        "display": dict(_DISPLAY),
    }


def slicer_document(markup: dict[str, Any]) -> dict[str, Any]:
    """A file as Slicer 5 saves it: its schema and one markup."""
    return {"@schema": SLICER_SCHEMA_URL, "markups": [markup]}


def slicer_save(path: Path, out_dir: Path) -> list[Path]:
    """Load ``path`` as Slicer does and save every node into ``out_dir`` as Slicer does."""
    doc = json.loads(path.read_text(encoding="utf-8"))
    stem = path.name[: -len(".mrk.json")] if path.name.endswith(".mrk.json") else path.stem
    written: list[Path] = []
    used: set[str] = set()
    for mk in doc["markups"]:
        name = mk.get("name") or stem
        node = name
        n = 1
        while node in used:  # Slicer's GetUniqueNameByString: name_1, name_2, ...
            node = f"{name}_{n}"
            n += 1
        used.add(node)
        cps = [
            slicer_control_point(
                i,
                cp.get("position"),
                label=cp.get("label", ""),
                description=cp.get("description", ""),
                status=cp.get("positionStatus", "defined"),
            )
            for i, cp in enumerate(mk.get("controlPoints", []))
        ]
        saved = slicer_markup(
            mk["type"],
            cps,
            system=mk.get("coordinateSystem", "LPS"),
            units="mm",
        )
        out = out_dir / f"{node}.mrk.json"
        out.write_text(json.dumps(slicer_document(saved), indent=4), encoding="utf-8")
        written.append(out)
    return written
