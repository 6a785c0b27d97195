"""Regenerate ``examples/campaign.json``: a two-run campaign with durability, written by the
command line, with the temporary folder's paths taken out. The docs' campaign reference lists its
keys (``benchmarks/doc_tables.py``), and ``tests/test_readme_commands.py`` checks that a fresh
campaign has the same ones.

    python examples/make_campaign_example.py
"""

from __future__ import annotations

import json
import os
import subprocess
import sys
import tempfile

HERE = os.path.dirname(os.path.abspath(__file__))
sys.path.insert(0, os.path.dirname(HERE))


def main() -> None:
    from benchmarks.validation import gen_campaign as gc

    with tempfile.TemporaryDirectory() as tmp:
        data, out = os.path.join(tmp, "data"), os.path.join(tmp, "out")
        design = gc.draw_campaign(2, 6107, n_shared=1, durations=(3.0, 3.0), rates=(200,), params=("m3",),
                                  motion_noise_share=0.0)
        gc.write_campaign(design, data, progress=False)
        subprocess.run([sys.executable, "-m", "jaxdrift", "-q", "campaign", "--manifest", "campaign.toml",
                        "--out", out, "--workers", "2", "--durability", "--paths", "4", "--no-figures"],
                       cwd=data, check=True)
        with open(os.path.join(out, "campaign.json")) as fh:
            text = json.dumps(json.load(fh), indent=1)
    text = text.replace(data + "/", "").replace(out + "/", "")
    with open(os.path.join(HERE, "campaign.json"), "w") as fh:
        fh.write(text + "\n")


if __name__ == "__main__":
    main()
