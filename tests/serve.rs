//! `lensblur serve` end to end, through a pipe as a host drives it: one request written, its
//! answer read, with the Vulkan validation layer on. Renders must equal the one-shot
//! `lensblur render` of the same file and camera; bad requests are answered and the server goes
//! on rendering.
mod common;

use std::io::{BufRead, BufReader, Write};
use std::path::Path;
use std::process::{Child, ChildStdin, ChildStdout, Command, Stdio};

use common::shot;
use lensblur::image::Image;
use lensblur::stack::{read_rgba, write_image, write_stack, ExtraChannel, SampleType, StackWriteOptions, WriteOptions};
use serde_json::{json, Value};

/// One-shot and served renders of the same job are the same computation: equal within float noise.
const TOLERANCE: f32 = 1e-5;

struct Server {
    child: Child,
    stdin: ChildStdin,
    stdout: BufReader<ChildStdout>,
}

impl Server {
    fn start() -> (Self, Value) {
        let mut child = Command::new(env!("CARGO_BIN_EXE_lensblur"))
            .arg("serve")
            .env("LENSBLUR_VALIDATION", "1")
            .stdin(Stdio::piped())
            .stdout(Stdio::piped())
            .spawn()
            .unwrap();
        let stdin = child.stdin.take().unwrap();
        let stdout = BufReader::new(child.stdout.take().unwrap());
        let mut server = Self { child, stdin, stdout };
        let greeting = server.read();
        (server, greeting)
    }

    fn read(&mut self) -> Value {
        let mut line = String::new();
        self.stdout.read_line(&mut line).unwrap();
        assert!(!line.is_empty(), "the server ended early");
        serde_json::from_str(&line).unwrap_or_else(|e| panic!("answer is not JSON ({e}): {line}"))
    }

    /// Sends `line` as it is (malformed ones too) and returns the answer.
    fn send_line(&mut self, line: &str) -> Value {
        writeln!(self.stdin, "{line}").unwrap();
        self.stdin.flush().unwrap();
        self.read()
    }

    fn send(&mut self, request: Value) -> Value {
        self.send_line(&request.to_string())
    }

    fn stop(mut self) {
        drop(self.stdin);
        let status = self.child.wait().unwrap();
        assert!(status.success(), "the server failed at the end of its input: {status}");
    }
}

fn ok(answer: &Value) -> &Value {
    assert_eq!(answer["ok"], json!(true), "the request failed: {answer}");
    answer
}

fn one_shot(input: &Path, output: &Path, args: &[&str]) -> Image {
    let result = Command::new(env!("CARGO_BIN_EXE_lensblur"))
        .args(["render", input.to_str().unwrap(), "-o", output.to_str().unwrap()])
        .args(args)
        .env("LENSBLUR_VALIDATION", "1")
        .output()
        .unwrap();
    assert!(result.status.success(), "{}", String::from_utf8_lossy(&result.stderr));
    read_rgba(output, None, u64::MAX).unwrap()
}

/// The shot's frame flattened into one RGB image and a Z pass: what most compositors hand over.
fn write_flat(path: &Path) {
    let stack = shot::stack(20);
    let (subject, wall) = (&stack.layers[0].rgba, &stack.layers[1].rgba);
    let image = Image::from_fn(stack.width, stack.height, |x, y| if subject.get(x, y)[3] > 0.0 { subject.get(x, y) } else { wall.get(x, y) });
    let depth = (0..stack.width * stack.height)
        .map(|i| if subject.pixels[i][3] > 0.0 { 2.0 } else { 4.0 })
        .collect();
    let extra = vec![ExtraChannel { name: "Z".into(), sample_type: SampleType::Float, values: depth }];
    let options = WriteOptions { sample_type: SampleType::Float, extra_channels: extra, ..WriteOptions::default() };
    write_image(path, &image, &options).unwrap();
}

#[test]
fn served_renders_equal_one_shot_renders_for_three_cameras_and_two_apertures() {
    let dir = common::temp_dir("serve", "equal");
    let layered = dir.join("layers.exr");
    write_stack(&layered, &shot::stack(20), &StackWriteOptions::default()).unwrap();
    let flat = dir.join("flat.exr");
    write_flat(&flat);

    // Whether the device lensblur uses is a CPU device (`lensblur devices` marks it `*`).
    let devices = String::from_utf8(common::lensblur(&["devices"], &[]).stdout).unwrap();
    let cpu_device = devices.lines().any(|line| line.starts_with('*') && line.ends_with("[CPU]"));
    let (mut server, greeting) = Server::start();
    assert_eq!(greeting["protocol"], json!("lensblur-serve"));
    assert_eq!(greeting["version"], json!(1));
    assert_eq!(ok(&server.send(json!({"id": 0, "op": "version"})))["version"], json!(1));
    for (input, name) in [(&layered, "layers"), (&flat, "flat")] {
        let loaded = server.send(json!({"id": name, "op": "load", "path": input}));
        let stack = ok(&loaded)["stack"].as_str().unwrap().to_string();
        assert_eq!((loaded["width"].clone(), loaded["height"].clone()), (json!(shot::WIDTH), json!(shot::HEIGHT)));
        let mut relayered = Vec::new();
        for (index, focus) in [2.0f32, 3.0, 4.0].into_iter().enumerate() {
            for aperture in ["disk", "polygon:6"] {
                let served = dir.join(format!("{name}-{index}-{}.exr", aperture.len()));
                let camera = json!({"focal_length_mm": 50, "sensor_width_mm": 3, "fstop": 1, "focus_distance": focus});
                let answer = server.send(json!({
                    "id": format!("{name}-{index}-{aperture}"), "op": "render", "stack": stack,
                    "camera": camera, "aperture": aperture, "output": served,
                }));
                ok(&answer);
                relayered.push(answer["relayered"].as_bool().unwrap());
                for key in ["layering", "render", "write", "total"] {
                    assert!(answer["timings_ms"][key].as_f64().unwrap() >= 0.0, "{answer}");
                }
                let args = ["--focal-length", "50", "--sensor-width", "3", "--fstop", "1", "--aperture", aperture];
                let expected = one_shot(input, &dir.join("one-shot.exr"), &[&args[..], &["--focus-distance", &focus.to_string()]].concat());
                let difference = common::max_abs_diff(&read_rgba(&served, None, u64::MAX).unwrap(), &expected);
                assert!(difference <= TOLERANCE, "{name}, focus {focus}, {aperture}: served and one-shot differ by {difference}");
                // A small frame through a disk renders where the one-shot render does: on a CPU
                // device (lavapipe) on the CPU path, with its very bytes; a hexagon on the device.
                assert_eq!(answer["cpu"], json!(aperture == "disk" && cpu_device), "{answer}");
                if aperture == "disk" && cpu_device {
                    assert_eq!(difference, 0.0, "{name}, focus {focus}: the CPU path's bytes");
                }
            }
        }
        // True layers are layered once; a flat image again for each new focus (its cut moves),
        // never for another aperture.
        let expected: Vec<bool> = match name {
            "layers" => vec![true, false, false, false, false, false],
            _ => vec![true, false, true, false, true, false],
        };
        assert_eq!(relayered, expected, "{name}");
        ok(&server.send(json!({"id": "close", "op": "close", "stack": stack})));
    }
    server.stop();
}

#[test]
fn bad_requests_are_answered_leave_nothing_behind_and_the_next_render_works() {
    let dir = common::temp_dir("serve", "bad");
    let input = dir.join("layers.exr");
    write_stack(&input, &shot::stack(20), &StackWriteOptions::default()).unwrap();
    let out = dir.join("out");
    std::fs::create_dir(&out).unwrap();
    let (mut server, _) = Server::start();
    let stack = ok(&server.send(json!({"id": 1, "op": "load", "path": input})))["stack"].as_str().unwrap().to_string();
    let camera = json!({"focal_length_mm": 50, "sensor_width_mm": 3, "fstop": 1, "focus_distance": 2});
    let render = |id: i64, stack: &str, output: &Path| {
        json!({"id": id, "op": "render", "stack": stack, "camera": camera, "output": output}).to_string()
    };
    let bad: Vec<(String, i64, &str)> = vec![
        (render(2, "s99", &out.join("a.exr")), 2, "no stack 's99'"),
        (render(3, &stack, &out.join("a.exr")).replace("\"fstop\":1", "\"fstop\":NaN"), 3, "malformed JSON"),
        (render(4, &stack, &out.join("a.exr")).replace("\"fstop\":1", "\"fstop\":\"nan\""), 4, "camera: invalid type"),
        (render(5, &stack, &out.join("a.exr")).replace("\"fstop\":1", "\"fstop\":-1"), 5, "fstop must be a positive number"),
        (json!({"id": 6, "op": "load", "path": dir.join("missing.exr")}).to_string(), 6, "missing.exr"),
        ("{\"id\": 7, \"op\": \"render\", \"stack\": ".into(), 7, "malformed JSON"),
        (render(8, &stack, &out.join("no-such-folder").join("a.exr")), 8, "no-such-folder"),
        (render(9, &stack, &out.join("a.tiff")), 9, "the output's extension picks its format"),
        (render(10, &stack, &out.join("a.exr")).replace("\"op\"", "\"near_blur\":-1,\"op\""), 10, "near blur multiplier"),
        (render(11, &stack, &out.join("a.exr")).replace("\"op\"", "\"nearblur\":2,\"op\""), 11, "unknown option 'nearblur'"),
        (json!({"id": 12, "op": "refocus"}).to_string(), 12, "unknown op 'refocus'"),
    ];
    for (line, id, message) in bad {
        let answer = server.send_line(&line);
        assert_eq!(answer["id"], json!(id), "{answer}");
        assert_eq!(answer["ok"], json!(false), "{answer}");
        let error = answer["error"].as_str().unwrap();
        assert!(error.contains(message), "request {id}: expected '{message}' in: {error}");
    }
    let written: Vec<_> = std::fs::read_dir(&out).unwrap().map(|e| e.unwrap().file_name()).collect();
    assert!(written.is_empty(), "a refused render left files behind: {written:?}");

    // The server goes on: a render to a file, and one to a mapped float32 buffer.
    let exr = out.join("a.exr");
    ok(&server.send_line(&render(20, &stack, &exr)));
    let raw = out.join("a.raw");
    let answer = server.send_line(&render(21, &stack, &raw));
    assert_eq!((answer["width"].clone(), answer["height"].clone()), (json!(shot::WIDTH), json!(shot::HEIGHT)), "{answer}");
    let bytes = std::fs::read(&raw).unwrap();
    assert_eq!(bytes.len(), shot::WIDTH * shot::HEIGHT * 4 * 4, "float32 RGBA");
    let floats: Vec<f32> = bytes.chunks_exact(4).map(|b| f32::from_le_bytes(b.try_into().unwrap())).collect();
    let image = read_rgba(&exr, None, u64::MAX).unwrap();
    assert_eq!(floats, image.as_flat(), "the raw buffer holds the EXR's pixels, row-major from the top");
    ok(&server.send(json!({"id": 22, "op": "close", "stack": stack})));
    let closed = server.send_line(&render(23, &stack, &exr));
    assert!(closed["error"].as_str().unwrap().contains("none is loaded"), "{closed}");
    server.stop();
}
