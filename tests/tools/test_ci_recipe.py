"""The CI recipe users copy, docs/ci/mission-tests.yml: the `run:` scripts of
its campaign jobs (one per matrix value) and of its merge job, run as GitHub
Actions runs them (bash -eo pipefail, the job's env, its expressions filled
in), on a campaign with a mission that fails: every shard job succeeds, the
merge job fails as the unsharded run does, and its output is that run's but
for the wall times. A shard job that left no output makes the merge job fail
naming the shard.

Run by tools/test-all.sh (after actionlint) with the pinned PyYAML;
ROTORPILOT_BIN points at the release binary.
"""
import glob
import json
import os
import shutil
import subprocess

import yaml

ROOT = os.path.dirname(os.path.dirname(os.path.dirname(os.path.abspath(__file__))))
BIN = os.environ.get("ROTORPILOT_BIN", os.path.join(ROOT, "target", "release", "rotorpilot"))
WORKFLOW = os.path.join(ROOT, "docs", "ci", "mission-tests.yml")

# a mission whose waypoint is out of reach in 5 s: it fails its verdict
FAILING_MISSION = """duration_s = 5
[mission]
[[mission.item]]
command = 16
params = [0.0, 1.0, 0.0, nan]
x = 47.3986
y = 8.5456
z = 20.0
"""


def step(job, name_prefix):
    """The `run:` script of the job's step whose name starts so."""
    found = [s for s in job["steps"] if s.get("name", "").startswith(name_prefix)]
    assert len(found) == 1, f"one step named {name_prefix}...: {job['steps']}"
    return found[0]["run"]


def fill(text, values):
    """The workflow expressions in `text` replaced by `values`; no other may remain."""
    for expr, value in values.items():
        text = text.replace("${{ " + expr + " }}", str(value))
    assert "${{" not in text, f"an expression this test does not fill in: {text}"
    return text


def run_script(script, env, cwd):
    """As a GitHub Actions `run:` step with the default shell on Linux."""
    path = os.path.join(cwd, ".step.sh")
    with open(path, "w") as f:
        f.write(script)
    return subprocess.run(["bash", "--noprofile", "--norc", "-eo", "pipefail", path], env=env, cwd=cwd,
                          capture_output=True, text=True, timeout=300)


def results(path):
    """The JSON lines of a campaign's output without the wall time."""
    lines = []
    with open(path) as f:
        for line in f:
            o = json.loads(line)
            o.pop("wall_time_s", None)
            lines.append(o)
    return lines


def fly_shards(tmp_path):
    """The campaign's files, the env of the workflow, and the directory
    holding every campaign job's output (as the merge job downloads them)."""
    with open(WORKFLOW) as f:
        wf = yaml.safe_load(f)
    campaign = tmp_path / "campaigns"
    campaign.mkdir()
    for name in ["fsr-exercise4.toml", "figure-eight-geometric.toml", "mission-square.toml", "quad-step-10m.toml"]:
        shutil.copy(os.path.join(ROOT, "tools", "scenarios", name), campaign)
    (campaign / "short-mission.toml").write_text(FAILING_MISSION)
    bindir = os.path.dirname(os.path.abspath(BIN))
    env = dict(os.environ, **{k: str(v) for k, v in wf["env"].items()})
    env.update(PATH=bindir + os.pathsep + os.environ["PATH"], CAMPAIGN=str(campaign),
               GITHUB_STEP_SUMMARY=str(tmp_path / "summary.md"))
    job = wf["jobs"]["campaign"]
    shards = job["strategy"]["matrix"]["shard"]
    assert len(shards) >= 2, shards
    downloaded = tmp_path / "merge-job" / "shards"
    downloaded.mkdir(parents=True)
    for shard in shards:
        values = {"matrix.shard": shard, "strategy.job-total": len(shards)}
        job_env = dict(env, **{k: fill(v, values) for k, v in job["env"].items()})
        workdir = tmp_path / f"campaign-job-{shard}"
        workdir.mkdir()
        ran = run_script(fill(step(job, "Fly shard"), values), job_env, workdir)
        # a failed mission is the merge's to report: the shard job is green
        assert ran.returncode == 0, f"shard {shard}: {ran.returncode}\n{ran.stdout}\n{ran.stderr}"
        assert f"shard {shard}/{len(shards)} of a campaign of 5" in ran.stderr, ran.stderr
        (output,) = glob.glob(str(workdir / "*.jsonl"))
        shutil.copy(output, downloaded)
    return wf, env, campaign, downloaded


def test_the_sharded_campaign_merges_into_the_unsharded_run(tmp_path):
    wf, env, campaign, downloaded = fly_shards(tmp_path)
    merge_dir = downloaded.parent
    ran = run_script(fill(step(wf["jobs"]["merge"], "Merge the shards"), {}), env, merge_dir)
    whole = subprocess.run([BIN, "simulate", str(campaign), "--json"], capture_output=True, text=True, timeout=300)
    assert whole.returncode == 1, whole.stderr
    assert ran.returncode == whole.returncode, f"{ran.returncode}\n{ran.stdout}\n{ran.stderr}"
    (tmp_path / "whole.jsonl").write_text(whole.stdout)
    merged = results(merge_dir / "campaign.jsonl")
    assert merged == results(tmp_path / "whole.jsonl")
    assert len(merged) == 6 and merged[-1]["shard"] == "0/1" and merged[-1]["failed"] == 1, merged[-1]
    # the failed mission and the tally: in the job's log and its summary
    summary = (tmp_path / "summary.md").read_text()
    for text in (ran.stdout, summary):
        assert "short-mission.toml" in text and '"verdict":"fail"' in text, text
        assert "5 scenarios from 4 shards" in text and "4 ok, 1 missions failed, 0 errors" in text, text


def test_a_shard_without_output_fails_the_merge_job_naming_it(tmp_path):
    wf, env, _, downloaded = fly_shards(tmp_path)
    lost = sorted(downloaded.iterdir())[2]
    lost.unlink()
    ran = run_script(fill(step(wf["jobs"]["merge"], "Merge the shards"), {}), env, downloaded.parent)
    assert ran.returncode == 2, f"{ran.returncode}\n{ran.stdout}\n{ran.stderr}"
    assert "merge refused: shard 2/4 missing" in ran.stdout, ran.stdout
    assert (downloaded.parent / "campaign.jsonl").read_text() == ""
