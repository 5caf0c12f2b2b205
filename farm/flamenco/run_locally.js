// Runs the Relume Flamenco job type without Flamenco: compiles a job with stand-ins for
// Flamenco's `author` and `path` (the same calls the Manager's JS API offers: author.Task,
// author.Command, task.addCommand / addDependency, job.addTask), checks the task graph
// (guide → partitions → merge), and with --run executes the tasks' "exec" commands in
// dependency order, as workers would. A check of the job definition, not of Flamenco.
//
//   node farm/flamenco/run_locally.js SCENE OUTPUT WORKDIR PARTITIONS "BAKE OPTIONS" RELUME [--run]

"use strict";
const fs = require("fs");
const vm = require("vm");
const nodePath = require("path");
const { execFileSync } = require("child_process");

const [scene, output, workdir, partitions, bakeOptions, relume, run] = process.argv.slice(2);
const tasks = [];
const author = {
  Task(name, type) {
    const t = { name, type, commands: [], deps: [] };
    t.addCommand = (c) => t.commands.push(c);
    t.addDependency = (d) => t.deps.push(d);
    return t;
  },
  Command(kind, params) {
    return { kind, params };
  },
};
const job = {
  settings: { scene, output, workdir, partitions: parseInt(partitions, 10), bake_options: bakeOptions, relume },
  addTask: (t) => tasks.push(t),
};
const source = fs.readFileSync(nodePath.join(__dirname, "relume-bake.js"), "utf8");
const context = { author, path: nodePath.posix, job };
vm.createContext(context);
vm.runInContext(source + "\ncompileJob(job); this.JOB_TYPE_LABEL = JOB_TYPE.label;", context);

// The graph: one guide, N partitions on it, a merge on every partition; exec commands only.
const n = job.settings.partitions;
const fail = (m) => { console.error("job type check: " + m); process.exit(1); };
if (tasks.length !== n + 2) fail(`${tasks.length} tasks for ${n} partitions`);
if (tasks[0].deps.length !== 0) fail("the guide depends on something");
for (let i = 1; i <= n; i++) if (tasks[i].deps.length !== 1 || tasks[i].deps[0] !== tasks[0]) fail(`partition ${i - 1} does not depend on the guide`);
if (tasks[n + 1].deps.length !== n) fail("the merge does not depend on every partition");
for (const t of tasks) for (const c of t.commands) if (c.kind !== "exec") fail(`command ${c.kind}`);
console.log(`${context.JOB_TYPE_LABEL}: ${tasks.length} tasks (guide, ${n} partitions, merge)`);

if (run === "--run") {
  fs.mkdirSync(workdir, { recursive: true });
  const done = new Set();
  while (done.size < tasks.length) {
    const ready = tasks.filter((t) => !done.has(t) && t.deps.every((d) => done.has(d)));
    if (ready.length === 0) fail("dependency cycle");
    for (const t of ready) {
      for (const c of t.commands) {
        execFileSync(c.params.exe, c.params.args, { stdio: ["ignore", "inherit", "inherit"] });
      }
      done.add(t);
      console.log(`task ${t.name} done`);
    }
  }
}
