// Where a `field` parameter (an mjModel array by name and flat index) is written back into MJCF:
// the table of the arrays that have an MJCF home (element type and attribute), next to the kind
// table of core/parameters.h, whose writers it reuses where a kind writes the same attribute.
//
// Contract:
// - A row of an array maps to one object: the row itself (geom_*: geom id, pair_*: pair id, ...),
//   the dof's joint (dof_*), or the actuator whose first output the row is (actuator_gear).
// - The writers copy the identified compiled value(s) into the element: array attributes are
//   written whole from the compiled row, so attributes MuJoCo fills in at compile time (a pair's
//   solref taken from its geoms) are written explicitly. dof_* arrays have one attribute per
//   joint: they are written only when every dof of the joint has the same identified value.
// - An array without a row here, or a row whose object or values cannot be written, returns a
//   target without writer: the caller warns that the value is not in the file.
#pragma once

#include <mujoco/mujoco.h>

#include <string>
#include <vector>

#include "core/parameters.h"

namespace mjsysid {

// An mjModel array with an MJCF home.
struct FieldMjcfInfo {
  const char* array;                              // the mjModel array, e.g. "pair_solref"
  mjtObj object;                                  // type of the element holding the attribute
  const char* attribute;                          // for docs: "`solref` of the `<pair>`"
  int (*object_of_row)(const mjModel&, int row);  // the object's id of a row; nullptr: the row
  MjcfWriter write_mjcf;                          // writes the identified value(s) of the object
};

// every array with an MJCF home, in mjModel order
const std::vector<FieldMjcfInfo>& FieldMjcfTable();

// the row of an array name; nullptr when the array has no MJCF home
const FieldMjcfInfo* FindFieldMjcf(const std::string& array);

// Where one parameter value goes in MJCF: the element type, the compiled id of the object, the
// component, and the writer (nullptr: the value has no MJCF home and is not written).
struct MjcfTarget {
  mjtObj object = mjOBJ_UNKNOWN;
  int id = -1;
  int index = 0;
  MjcfWriter write_mjcf = nullptr;
};

// The target of a parameter resolved in m: its kind's object and writer, or for `field` the
// array's row in FieldMjcfTable() (flat index split into row and column).
MjcfTarget MjcfTargetOf(const mjModel& m, const Parameter& p, const ParameterSpec& spec);

}  // namespace mjsysid
