"""`hoverfly log csv`: one CSV per topic (pyulog's flattened field names), like pyulog's ulog2csv.

Columns: timestamp (µs), t_s (from the log's start), then the topic's fields in log order.
"""

import csv
import os

_SAFE = frozenset("abcdefghijklmnopqrstuvwxyzABCDEFGHIJKLMNOPQRSTUVWXYZ0123456789_-")


def file_part(name):
    """A topic name as part of a file name: letters, digits, '_' and '-' kept, anything else '_'. The
    name comes from the file's own format text, which may hold '/', '..' or a NUL."""
    return "".join(c if c in _SAFE else "_" for c in name[:100]) or "_"


def write_csv(log, out_dir, topics=None):
    """Write <out_dir>/<stem>_<topic>.csv for each topic (all, or those named); returns the paths."""
    os.makedirs(out_dir, exist_ok=True)
    stem = os.path.splitext(os.path.basename(log.path))[0]
    paths = []
    for d in log.ulog.data_list:
        if d.multi_id != 0 or (topics and d.name not in topics) or d.name not in log.topics:
            continue
        data = log.topics[d.name]
        names = ["timestamp", "t_s"] + [f.field_name for f in d.field_data if f.field_name != "timestamp"]
        path = os.path.join(out_dir, "%s_%s.csv" % (stem, file_part(d.name)))
        while path in paths:  # two names that differ only in unsafe characters
            path = path[:-4] + "_.csv"
        cols = [data[n] for n in names]
        with open(path, "w", newline="") as f:
            w = csv.writer(f)
            w.writerow(names)
            for i in range(len(cols[0])):
                w.writerow([c[i].item() for c in cols])
        paths.append(path)
    return paths
