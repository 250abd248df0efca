"""Rerun entities as Arrow columns: one record batch carries every entity of a flush (entity
paths, component metadata, the time index)."""
from __future__ import annotations

import numpy as np
import pyarrow as pa
import rerun as rr

TIMELINE = "sim_time"


def entity_part(name: str) -> str:
    return rr.escape_entity_path_part(name)


def xyzw(wxyz) -> np.ndarray:
    q = np.asarray(wxyz, float)
    return q[..., [1, 2, 3, 0]]


def ns(t) -> np.ndarray:
    return np.rint(np.asarray(t, float) * 1e9).astype(np.int64)


# -- Arrow fields that describe Rerun components (one record batch carries every entity) ------
def component_meta(path: str, archetype: str, component: str, component_type: str) -> dict:
    return {"rerun:entity_path": path, "rerun:archetype": f"rerun.archetypes.{archetype}",
            "rerun:component": component, "rerun:component_type": f"rerun.components.{component_type}",
            "rerun:kind": "data"}


def scalar_field(path: str) -> pa.Field:
    return pa.field(f"{path}:Scalars:scalars", pa.float64(),
                    metadata=component_meta(path, "Scalars", "Scalars:scalars", "Scalar"))


def transform_fields(path: str) -> list[pa.Field]:
    return [pa.field(f"{path}:Transform3D:translation", pa.list_(pa.float32(), 3),
                     metadata=component_meta(path, "Transform3D", "Transform3D:translation", "Translation3D")),
            pa.field(f"{path}:Transform3D:quaternion", pa.list_(pa.float32(), 4),
                     metadata=component_meta(path, "Transform3D", "Transform3D:quaternion", "RotationQuat"))]


TIME_FIELD = pa.field(TIMELINE, pa.duration("ns"), metadata={"rerun:index_name": TIMELINE, "rerun:kind": "index"})


def vec_array(x: np.ndarray, n: int) -> pa.Array:
    return pa.FixedSizeListArray.from_arrays(pa.array(np.ascontiguousarray(x, np.float32).ravel()), n)
