"""Task-set files: link/message conversion, CSV, chains."""

import pytest

from c4d_sched import TaskSetError
from c4d_sched.taskio import taskset_from_csv, taskset_from_dict


def test_messages_convert_to_bit_times():
    ts = taskset_from_dict({"link": {"bits_per_second": 57600, "bits_per_byte": 10, "overhead_bytes": 8},
                            "messages": [{"name": "A", "period_s": 0.02, "bytes": 12}]})
    assert (ts.tasks[0].period, ts.tasks[0].wcet) == (1152, 200)
    with pytest.raises(TaskSetError, match="not an integer"):
        taskset_from_dict({"link": {"bits_per_second": 57600}, "messages": [{"period_s": 0.00001, "bytes": 1}]})


def test_csv_offsets_and_chains():
    ts = taskset_from_csv("name,period,wcet,offset\na,10,2,3\nb,20,1,\n")
    assert [t.offset for t in ts.tasks] == [3, None]
    ts = taskset_from_dict({"tasks": [{"name": "a", "period": 10, "wcet": 1}, {"name": "b", "period": 10, "wcet": 2}],
                            "chains": [{"tasks": ["a", "b"], "separation": 2}]})
    assert ts.chains[0].tasks == ("a", "b") and ts.chains[0].separation == 2
    with pytest.raises(TaskSetError, match="unknown key"):
        taskset_from_dict({"tasks": [{"name": "a", "period": 10, "wcet": 1, "phase": 2}]})
