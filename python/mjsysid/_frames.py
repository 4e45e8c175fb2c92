"""The pandas tables of the results' to_pandas() (python/src/result_dict.cc calls these).

The parameters' table is made from to_dict(), so its columns are result.yaml's keys: the pair
`ci95` split into ci95_low and ci95_high (result.h5's names), the list `flags` into one bool
column per flag. pandas is imported here, when a table is asked for, not by `import mjsysid`.
"""

import math

def _pandas():
    try:
        import pandas
    except ImportError as e:
        raise ImportError(
            "to_pandas() needs pandas, which mjsysid does not install: pip install pandas "
            "(to_dict() and the attributes need nothing more)") from e
    return pandas


def parameters_frame(result, flags):
    """One row per estimated value of `result` (a to_dict() dict), indexed by name; `flags`: the
    names a parameter's `flags` may list (sysid/io/result_fields.h kFlags), one bool column each."""
    pd = _pandas()
    columns = {}
    names = []
    for row, p in enumerate(result["parameters"]):
        names.append(p["name"])
        cells = {}
        for key, value in p.items():
            if key == "name":
                continue
            if key == "ci95":
                cells["ci95_low"], cells["ci95_high"] = value
            elif key == "flags":
                for flag in flags:
                    cells[flag] = flag in value
            else:
                cells[key] = value
        for key, value in cells.items():
            # a key some parameters have (truth, timestep_bias): NaN for the others
            columns.setdefault(key, [math.nan] * row).append(value)
        for key, values in columns.items():
            if len(values) == row:
                values.append(math.nan)
    return pd.DataFrame(columns, index=pd.Index(names, name="name"))


def sequence_frame(channels, time, measured, simulated_initial, simulated_final,
                   simulated_one_piece):
    """One row per sample: time, then measured:CHANNEL, simulated_initial:CHANNEL, ..."""
    pd = _pandas()
    columns = {"time": time}
    arrays = [("measured", measured), ("simulated_initial", simulated_initial),
              ("simulated_final", simulated_final)]
    if simulated_one_piece.shape[0] > 0:
        arrays.append(("simulated_one_piece", simulated_one_piece))
    for c, channel in enumerate(channels):
        for what, array in arrays:
            if array.shape[0] == len(time) and array.shape[1] > c:
                columns[f"{what}:{channel}"] = array[:, c]
    return pd.DataFrame(columns)
