//! `lensblur serve`: a resident renderer that speaks JSON lines on stdin and stdout, as a
//! language server does, for hosts that pull focus interactively (the Blender add-on's Live
//! mode, a compositing script). Each loaded stack is a library [`Session`]: read once, its
//! device and pipelines kept, re-layered only when a camera changes the cut. The protocol is
//! documented in the book (`docs/book/src/serve.md`); [`PROTOCOL_VERSION`] changes when a
//! request or answer changes incompatibly.
//!
//! A reader thread takes requests off stdin while the main thread renders, so that a render
//! request for a stack replaces one still queued for it (a host dragging a slider wants its
//! latest value, not every value in between) and a malformed line is answered at once.
use std::collections::{HashMap, VecDeque};
use std::io::{BufRead, Write};
use std::path::{Path, PathBuf};
use std::sync::{Arc, Condvar, Mutex};
use std::time::Instant;

use lensblur::image::Image;
use lensblur::input::ReadInput;
use lensblur::job::{CameraValues, JobOptions, OptionSet, RenderJob};
use lensblur::render::placement::{place, CpuReason, DevicePreference, Placement};
use lensblur::render::Method;
use lensblur::session::Session;
use lensblur::stack::{write_image, write_ldr, OutputFormat, SampleType, WriteOptions};
use lensblur::vk::{Context, ContextOptions};
use serde_json::{json, Map, Value};

use super::render::{ms, DeviceChoice};

/// The protocol's version, in the greeting and the `version` answer.
pub const PROTOCOL_VERSION: u32 = 1;

const EXAMPLES: &str = "\
Requests and answers are one JSON object per line. The first line out is a greeting:
  {\"event\":\"ready\",\"protocol\":\"lensblur-serve\",\"version\":1,\"lensblur\":\"0.1.0\"}
Then, for example:
  {\"id\":1,\"op\":\"load\",\"path\":\"shot.exr\"}
  -> {\"id\":1,\"ok\":true,\"stack\":\"s1\",\"width\":1920,\"height\":1080,...}
  {\"id\":2,\"op\":\"render\",\"stack\":\"s1\",\"output\":\"/tmp/out.exr\",
   \"camera\":{\"focal_length_mm\":50,\"fstop\":2,\"focus_distance\":3},\"near_blur\":1.5}
  -> {\"id\":2,\"ok\":true,\"output\":\"/tmp/out.exr\",\"timings_ms\":{...},...}
  {\"id\":3,\"op\":\"close\",\"stack\":\"s1\"}
Ops: load (path, method, file options), render (stack, output, camera, render options),
close (stack), version, shutdown. A bad request is answered {\"id\":..,\"ok\":false,\"error\":..}
and the server goes on. An output ending in .raw is float32 RGBA, row-major, top row first (a
host maps it, e.g. under /dev/shm); .exr, .png, .jpg as `lensblur render -o` writes them; every
output appears whole (written, then renamed). A render queued behind another for the same stack
is answered {\"ok\":false,\"superseded_by\":ID} when a newer one arrives.

Examples:
  lensblur serve
  printf '%s\\n' '{\"id\":1,\"op\":\"load\",\"path\":\"example-out/layers.exr\"}' | lensblur serve";

#[derive(clap::Args)]
#[command(after_help = EXAMPLES)]
pub struct Args {
    /// Where Vulkan methods run: auto (the Vulkan device; the CPU, with a warning, if none can
    /// be opened), gpu (fail a load without one), cpu (the CPU references).
    #[arg(long, value_enum, default_value = "auto")]
    pub device: DeviceChoice,
}

/// One request off stdin, with its id (`null` when it had none or could not be parsed).
struct Request {
    id: Value,
    op: String,
    body: Map<String, Value>,
}

impl Request {
    fn stack(&self) -> Option<&str> {
        self.body.get("stack").and_then(Value::as_str)
    }
}

/// Answers go out one whole line at a time, from either thread.
#[derive(Clone)]
struct Answers(Arc<Mutex<std::io::Stdout>>);

impl Answers {
    fn send(&self, answer: Value) {
        let mut out = self.0.lock().unwrap_or_else(|e| e.into_inner());
        // A host that closed its end gets no answers; the server ends at stdin's end.
        let _ = writeln!(out, "{answer}").and_then(|()| out.flush());
    }

    fn error(&self, id: &Value, error: impl std::fmt::Display) {
        self.send(json!({"id": id, "ok": false, "error": error.to_string()}));
    }
}

/// The requests waiting for the renderer, and whether stdin has ended.
#[derive(Default)]
struct Queue {
    state: Mutex<(VecDeque<Request>, bool)>,
    changed: Condvar,
}

impl Queue {
    /// Queues `request`; a render request answers, and drops, a render of the same stack that
    /// is still waiting.
    fn push(&self, request: Request, answers: &Answers) {
        let mut state = self.state.lock().unwrap_or_else(|e| e.into_inner());
        if request.op == "render" {
            if let Some(stack) = request.stack() {
                let older = state.0.iter().position(|r| r.op == "render" && r.stack() == Some(stack));
                if let Some(older) = older.and_then(|i| state.0.remove(i)) {
                    answers.send(json!({
                        "id": older.id, "ok": false, "superseded_by": request.id,
                        "error": format!("superseded by request {} for stack {stack} before it started", request.id),
                    }));
                }
            }
        }
        state.0.push_back(request);
        self.changed.notify_one();
    }

    fn end(&self) {
        self.state.lock().unwrap_or_else(|e| e.into_inner()).1 = true;
        self.changed.notify_one();
    }

    /// The next request; None once stdin has ended and nothing is left.
    fn pop(&self) -> Option<Request> {
        let mut state = self.state.lock().unwrap_or_else(|e| e.into_inner());
        loop {
            if let Some(request) = state.0.pop_front() {
                return Some(request);
            }
            if state.1 {
                return None;
            }
            state = self.changed.wait(state).unwrap_or_else(|e| e.into_inner());
        }
    }
}

/// A request line, or the answer to a line that is not one (with the id, when it can be found).
fn parse(line: &str) -> Result<Request, (Value, String)> {
    let value: Value = serde_json::from_str(line).map_err(|e| (salvage_id(line), format!("malformed JSON: {e}")))?;
    let Value::Object(mut body) = value else {
        return Err((Value::Null, "a request is a JSON object: {\"id\": ..., \"op\": ...}".into()));
    };
    let id = body.remove("id").unwrap_or(Value::Null);
    match body.remove("op") {
        Some(Value::String(op)) => Ok(Request { id, op, body }),
        _ => Err((id, "no \"op\": give one of load, render, close, version, shutdown".into())),
    }
}

/// The `"id"` value of a line that is not valid JSON as a whole (a NaN camera that a host's
/// JSON writer let through), so that its answer still reaches its caller.
fn salvage_id(line: &str) -> Value {
    let Some(at) = line.find("\"id\"") else { return Value::Null };
    let rest = line[at + 4..].trim_start();
    let Some(rest) = rest.strip_prefix(':') else { return Value::Null };
    serde_json::Deserializer::from_str(rest).into_iter::<Value>().next().and_then(Result::ok).unwrap_or(Value::Null)
}

/// A loaded stack: its session, and the options it was loaded with (the defaults of its renders).
struct Stack {
    session: Session,
    path: PathBuf,
    options: Map<String, Value>,
}

/// The renderer's state: one device for every stack.
struct Server {
    preference: DevicePreference,
    context: Option<Option<Arc<Context>>>,
    stacks: HashMap<String, Stack>,
    loads: usize,
    answers: Answers,
}

pub fn run(args: Args) -> anyhow::Result<()> {
    let answers = Answers(Arc::new(Mutex::new(std::io::stdout())));
    answers.send(json!({
        "event": "ready", "protocol": "lensblur-serve", "version": PROTOCOL_VERSION, "lensblur": env!("CARGO_PKG_VERSION"),
    }));
    let queue = Arc::new(Queue::default());
    let reader = {
        let (queue, answers) = (Arc::clone(&queue), answers.clone());
        std::thread::spawn(move || {
            for line in std::io::stdin().lock().lines() {
                let Ok(line) = line else { break };
                if line.trim().is_empty() {
                    continue;
                }
                match parse(&line) {
                    Ok(request) => queue.push(request, &answers),
                    Err((id, error)) => answers.error(&id, error),
                }
            }
            queue.end();
        })
    };
    let mut server =
        Server { preference: args.device.preference(), context: None, stacks: HashMap::new(), loads: 0, answers };
    while let Some(request) = queue.pop() {
        let id = request.id.clone();
        let shutdown = request.op == "shutdown";
        match server.handle(request) {
            Ok(answer) => server.answers.send(answer),
            Err(error) => server.answers.error(&id, error),
        }
        if shutdown {
            break;
        }
    }
    // Each session's pipelines and stack go before the device they were made on.
    for (_, stack) in server.stacks.drain() {
        stack.session.close()?;
    }
    drop(server.context);
    // At a shutdown request the reader may still wait on stdin: the process ends without it.
    if reader.is_finished() {
        let _ = reader.join();
    }
    Ok(())
}

impl Server {
    fn handle(&mut self, request: Request) -> Result<Value, String> {
        let Request { id, op, mut body } = request;
        let mut take = |key: &str| body.remove(key);
        match op.as_str() {
            "version" | "shutdown" => {
                Ok(json!({"id": id, "ok": true, "version": PROTOCOL_VERSION, "lensblur": env!("CARGO_PKG_VERSION")}))
            }
            "load" => {
                let path = PathBuf::from(string(take("path"), "path", "the stack's file")?);
                self.load(id, path, body)
            }
            "render" => {
                let name = string(take("stack"), "stack", "the handle a load answered")?;
                let output = PathBuf::from(string(take("output"), "output", "the file to write (.exr, .png, .jpg, .raw)")?);
                let camera = take("camera").filter(|c| !c.is_null()).map(CameraValues::from_json).transpose();
                let camera = camera.map_err(|e| e.to_string())?;
                self.render(id, &name, camera, &output, body)
            }
            "close" => {
                let name = string(take("stack"), "stack", "the handle a load answered")?;
                let stack = self.stacks.remove(&name).ok_or_else(|| self.unknown(&name))?;
                stack.session.close().map_err(|e| e.to_string())?;
                Ok(json!({"id": id, "ok": true, "stack": name}))
            }
            other => Err(format!("unknown op '{other}': the ops are load, render, close, version, shutdown")),
        }
    }

    fn unknown(&self, name: &str) -> String {
        let mut open: Vec<&str> = self.stacks.keys().map(String::as_str).collect();
        open.sort_unstable();
        let open = if open.is_empty() { "none is loaded".to_string() } else { format!("loaded: {}", open.join(", ")) };
        format!("no stack '{name}' ({open}; a load answers a handle, a close ends it)")
    }

    /// The device every session shares, opened at the first load (None: the CPU references).
    fn context(&mut self) -> Result<Option<Arc<Context>>, String> {
        if let Some(context) = &self.context {
            return Ok(context.clone());
        }
        let context = match place(Method::DrBokeh, self.preference, &ContextOptions::from_env()) {
            Ok(Placement::Gpu(context)) => Some(Arc::new(context)),
            Ok(Placement::Cpu(CpuReason::NoDevice(error))) => {
                eprintln!("lensblur serve: warning: no usable Vulkan device ({error}); rendering on the CPU (slow)");
                None
            }
            Ok(Placement::Cpu(_)) => None,
            Err(error) => return Err(format!("opening the Vulkan device: {error} (see `lensblur devices`; --device cpu serves without one)")),
        };
        self.context = Some(context.clone());
        Ok(context)
    }

    /// The render job of `options` (the load's and the render's) through `camera` (None: the
    /// file's header), its Vulkan methods placed as the server was told.
    fn job(&self, options: Map<String, Value>, camera: Option<&CameraValues>) -> Result<RenderJob, String> {
        let parsed = JobOptions::from_json(options, OptionSet::File).map_err(|e| e.to_string())?;
        let mut spec = parsed.spec(camera, Method::default()).map_err(|e| e.to_string())?;
        spec.device = self.preference;
        RenderJob::new(spec).map_err(|e| e.to_string())
    }

    fn load(&mut self, id: Value, path: PathBuf, options: Map<String, Value>) -> Result<Value, String> {
        let start = Instant::now();
        // The load's options are every render's defaults: checked as a job now.
        let job = self.job(options.clone(), None)?;
        let read = ReadInput::read(&path, &job.spec().input).map_err(|e| e.with_causes())?;
        let (width, height) = read.size();
        let context = self.context()?;
        self.loads += 1;
        let name = format!("s{}", self.loads);
        let session = Session::new(context, read);
        self.stacks.insert(name.clone(), Stack { session, path, options });
        Ok(json!({
            "id": id, "ok": true, "stack": name, "width": width, "height": height,
            "timings_ms": {"load": ms(start.elapsed())},
        }))
    }

    fn render(
        &mut self,
        id: Value,
        name: &str,
        camera: Option<CameraValues>,
        output: &Path,
        options: Map<String, Value>,
    ) -> Result<Value, String> {
        let start = Instant::now();
        let format = output_format(output)?;
        // A render takes no file option: the stack was read with the load's.
        JobOptions::from_json(options.clone(), OptionSet::Render).map_err(|e| e.to_string())?;
        let Some(stack) = self.stacks.get(name) else { return Err(self.unknown(name)) };
        // The render's options over the load's.
        let mut merged = stack.options.clone();
        merged.extend(options);
        let job = self.job(merged, camera.as_ref())?;
        let stack = self.stacks.get_mut(name).expect("looked up above");
        let (image, stats) = stack.session.render(&job).map_err(|e| format!("{}: {}", stack.path.display(), e.with_causes()))?;
        let writing = Instant::now();
        write(output, format, &image).map_err(|e| e.with_causes())?;
        Ok(json!({
            "id": id, "ok": true, "output": output, "width": image.width, "height": image.height,
            "relayered": stats.relayered, "prepared": stats.prepared, "cpu": stats.cpu,
            "timings_ms": {
                "layering": stats.layering_ms, "render": stats.render_ms, "write": ms(writing.elapsed()), "total": ms(start.elapsed()),
            },
        }))
    }
}

fn string(value: Option<Value>, key: &str, what: &str) -> Result<String, String> {
    match value {
        Some(Value::String(text)) => Ok(text),
        Some(other) => Err(format!("\"{key}\" is a string ({what}), got {other}")),
        None => Err(format!("this op needs \"{key}\": {what}")),
    }
}

/// How an output is written: by its extension, `.raw` being float32 RGBA for a host to map.
#[derive(Clone, Copy)]
enum Written {
    Raw,
    Format(OutputFormat),
}

fn output_format(path: &Path) -> Result<Written, String> {
    if path.extension().is_some_and(|e| e.eq_ignore_ascii_case("raw")) {
        return Ok(Written::Raw);
    }
    OutputFormat::from_extension(path).map(Written::Format).ok_or_else(|| {
        format!("{}: the output's extension picks its format: .exr, .png, .jpg/.jpeg or .raw (float32 RGBA)", path.display())
    })
}

fn write(path: &Path, format: Written, image: &Image) -> lensblur::Result<()> {
    match format {
        Written::Raw => lensblur::atomic_file::write_atomically(path, |out| {
            // Little-endian float32, as every host this runs on reads it natively.
            image
                .as_flat()
                .iter()
                .try_for_each(|value| out.write_all(&value.to_le_bytes()))
                .map_err(lensblur::Error::io(path))
        }),
        Written::Format(OutputFormat::Exr) => {
            // Float, as `lensblur render` writes by default: a host compares and composites it.
            write_image(path, image, &WriteOptions { sample_type: SampleType::Float, ..WriteOptions::default() })
        }
        Written::Format(_) => write_ldr(path, image),
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_malformed_line_keeps_its_id_when_one_can_be_read() {
        let (id, error) = parse(r#"{"id": 7, "op": "render", "camera": {"fstop": NaN}}"#).err().unwrap();
        assert_eq!(id, json!(7));
        assert!(error.starts_with("malformed JSON"), "{error}");
        assert_eq!(parse("not json").err().unwrap().0, Value::Null);
        assert_eq!(parse(r#"{"id": "a", "op": 3}"#).err().unwrap().0, json!("a"));
    }

    #[test]
    fn a_newer_render_of_a_stack_replaces_the_queued_one() {
        let queue = Queue::default();
        let answers = Answers(Arc::new(Mutex::new(std::io::stdout())));
        let request = |id: i64, op: &str, stack: &str| Request {
            id: json!(id),
            op: op.into(),
            body: Map::from_iter([("stack".to_string(), json!(stack))]),
        };
        for r in [request(1, "render", "s1"), request(2, "render", "s2"), request(3, "render", "s1"), request(4, "close", "s1")] {
            queue.push(r, &answers);
        }
        queue.end();
        let ids: Vec<Value> = std::iter::from_fn(|| queue.pop()).map(|r| r.id).collect();
        assert_eq!(ids, [json!(2), json!(3), json!(4)]);
    }
}
