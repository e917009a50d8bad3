"""A linkage file of any size for the tests of limits (file, configurations): a crank driving a
chain of RRR dyads, each on a ground pivot."""

from __future__ import annotations


def chain_of_dyads(n: int) -> str:
    """A crank and n RRR dyads in a chain, each on a ground pivot (2^n configurations)."""
    lines = [
        'name = "chain"',
        "[ground]",
        "A0 = [0, 0]",
        *(f"G{i} = [{20 * i}, 25]" for i in range(1, n + 1)),
        "[links.crank]",
        'joints = ["A0", "J0"]',
        "length = 10",
    ]
    for i in range(1, n + 1):
        lines += [
            f"[links.a{i}]",
            f'joints = ["J{i - 1}", "J{i}"]',
            "length = 22",
            f"[links.b{i}]",
            f'joints = ["G{i}", "J{i}"]',
            "length = 22",
        ]
    return "\n".join([*lines, "[[inputs]]", 'joint = "A0"', 'link = "crank"']) + "\n"
