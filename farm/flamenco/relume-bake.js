// SPDX-License-Identifier: MIT OR Apache-2.0
//
// Flamenco 3 job type: a Relume bake split over the farm by eye-sample ranges.
//
//   relume-guide          `relume bake SCENE OPTIONS --guide-only -o WORKDIR/guide.rguide`
//   relume-partition-i    `relume bake SCENE OPTIONS --partition i/N --guide … -o WORKDIR/part_i.rpart`
//                         (i = 0 … N-1, each depending on the guide task)
//   relume-merge          `relume merge WORKDIR/part_*.rpart --scene SCENE -o OUTPUT`
//                         (depending on every partition)
//
// The merged stack is bit-identical to `relume bake SCENE OPTIONS -o OUTPUT` on one machine.
// Install: copy this file into the Manager's `scripts/` folder (next to flamenco-manager) and
// restart the Manager; submit with the Flamenco add-on or the Manager's API. Workers need
// `relume` (setting "relume": a path or a name on PATH) and must see WORKDIR (shared storage).
// Flamenco itself cannot run on the machines this was written on: the job type was checked
// only by running compileJob under node with a stand-in `author`/`path` (docs/farm.md).

const JOB_TYPE = {
  label: "Relume Bake",
  description: "Bake a Relume scene file into a transfer stack on N workers (guide → partitions → merge)",
  settings: [
    { key: "scene", type: "string", subtype: "file_path", required: true,
      description: "Exported Relume scene file (relume-scene JSON), on shared storage" },
    { key: "output", type: "string", subtype: "file_path", required: true,
      description: "Stack to write (OpenEXR)" },
    { key: "workdir", type: "string", subtype: "dir_path", required: true,
      description: "Shared folder for the guide file and the partial stacks" },
    { key: "partitions", type: "int32", default: 8, required: true,
      description: "Tasks the eye samples are split into (at most spp; a power of two dividing spp keeps parts smallest)" },
    { key: "bake_options", type: "string", default: "--preset final",
      description: "relume bake options shared by every task (preset, spp, seed, light groups…)" },
    { key: "relume", type: "string", default: "relume",
      description: "The relume binary on the workers" },
  ],
};

function compileJob(job) {
  const s = job.settings;
  const n = s.partitions;
  if (!(n >= 1)) {
    throw `partitions must be ≥ 1, got ${n}`;
  }
  const options = (s.bake_options || "").split(/\s+/).filter((a) => a.length > 0);
  const guide = path.join(s.workdir, "guide.rguide");

  const guideTask = author.Task("relume-guide", "misc");
  guideTask.addCommand(author.Command("exec", {
    exe: s.relume,
    args: ["bake", s.scene, ...options, "--guide-only", "-o", guide],
  }));
  job.addTask(guideTask);

  const parts = [];
  const partTasks = [];
  for (let i = 0; i < n; i++) {
    const part = path.join(s.workdir, `part_${i}.rpart`);
    const task = author.Task(`relume-partition-${i}`, "misc");
    task.addCommand(author.Command("exec", {
      exe: s.relume,
      args: ["bake", s.scene, ...options, "--partition", `${i}/${n}`, "--guide", guide, "-o", part],
    }));
    task.addDependency(guideTask);
    job.addTask(task);
    parts.push(part);
    partTasks.push(task);
  }

  const mergeTask = author.Task("relume-merge", "misc");
  mergeTask.addCommand(author.Command("exec", {
    exe: s.relume,
    args: ["merge", ...parts, "--scene", s.scene, "-o", s.output],
  }));
  for (const t of partTasks) {
    mergeTask.addDependency(t);
  }
  job.addTask(mergeTask);
}
