//! `citygen kb edit`: the knowledge base edited in a browser (docs/kb-editor.md).
//!
//! A local web server on `std::net` (no async runtime): it binds 127.0.0.1 only, on the given
//! port or a free one, and answers one request per connection with bounded resources
//! (`conn`: a cap on open connections, head and request timeouts, size caps, a fixed pool of
//! workers; `http`: heads parsed by `httparse`). Every
//! request must come with the session's token (128 bits from the system's random source:
//! `?token=` for the page and its scripts, the `X-Citygen-Token` header for the API), a `Host`
//! that is this server's (`127.0.0.1:PORT` or `localhost:PORT`, so a DNS-rebound name is
//! refused) and, when it has one, an `Origin` that is this server's. The page and its scripts
//! are compiled into the binary (`assets/kb-edit/`).
//!
//! The KB being edited is a `draft::Draft` behind a mutex; each edit goes through
//! [`crate::kb::edit`] and is checked as `kb check --strict` checks a file before the draft
//! takes it. Saving writes the KB file only (atomically; a KB read leniently in the strict format,
//! [`crate::kb::write`]); rulesets are written only inside its
//! folder.

mod conn;
pub mod draft;
pub mod http;

use std::io::Read;
use std::net::TcpListener;
use std::path::PathBuf;
use std::sync::{Arc, Mutex};

use serde_json::{json, Value};

use crate::model::Lod;
use crate::pipeline::{building, Source};
use crate::prepare::Site;
use draft::{Draft, Edit};
use http::{Request, Response};

/// What `citygen kb edit` is given.
#[derive(Clone, Debug)]
pub struct EditOptions {
    /// The knowledge base to edit (the one file saved).
    pub kb: PathBuf,
    /// The footprints shown on the map and previewed (`--osm` or `--shp`).
    pub source: Option<Source>,
    /// The port (`--port`); 0 picks a free one.
    pub port: u16,
    /// The seed of the appearance picks and previews (`--seed`).
    pub seed: u64,
}

/// The page's files, compiled in.
const INDEX_HTML: &str = include_str!("../../assets/kb-edit/index.html");
const APP_JS: &str = include_str!("../../assets/kb-edit/app.js");
const VIEWER_JS: &str = include_str!("../../assets/kb-edit/viewer.js");
const STYLE_CSS: &str = include_str!("../../assets/kb-edit/style.css");

/// The input's footprints: the prepared site and what the map draws of it.
struct Footprints {
    site: Site,
    name: String,
    /// `[{i, id, rings, at}]` as JSON bytes, made once.
    json: Vec<u8>,
}

/// A bound editor, ready to serve.
pub(crate) struct Editor {
    listener: TcpListener,
    port: u16,
    token: String,
    draft: Arc<Mutex<Draft>>,
    footprints: Arc<Option<Footprints>>,
    seed: u64,
    scratch: PathBuf,
}

/// Why the editor does not start.
#[derive(Debug, thiserror::Error)]
pub enum EditorError {
    /// The KB does not open.
    #[error(transparent)]
    Draft(#[from] draft::DraftError),
    /// The footprints (`--osm`, `--shp`) do not load.
    #[error(transparent)]
    Footprints(#[from] crate::pipeline::RunError),
    /// The port cannot be bound.
    #[error("binding 127.0.0.1:{port}: {source}")]
    Bind {
        /// The port asked for.
        port: u16,
        /// The system's error.
        source: std::io::Error,
    },
    /// The bound address cannot be read.
    #[error("the bound address: {0}")]
    Address(std::io::Error),
    /// No random bytes for the session token.
    #[error("no random source for the session token (/dev/urandom): {0}")]
    Token(std::io::Error),
}

/// 128 random bits from the system, as 32 hex digits.
fn new_token() -> Result<String, EditorError> {
    let mut bytes = [0u8; 16];
    std::fs::File::open("/dev/urandom")
        .and_then(|mut f| f.read_exact(&mut bytes))
        .map_err(EditorError::Token)?;
    Ok(crate::fsio::hex(&bytes))
}

fn footprints_json(site: &Site) -> Vec<u8> {
    let round = |x: f64| (x * 1e7).round() / 1e7;
    let list: Vec<Value> = site
        .lots
        .iter()
        .enumerate()
        .map(|(i, lot)| {
            let rings: Vec<Vec<[f64; 2]>> = lot
                .polygons
                .iter()
                .map(|p| {
                    p.outer
                        .iter()
                        .map(|v| {
                            let (lon, lat) =
                                site.crs.to_lonlat(v.x + site.origin.x, v.y + site.origin.y);
                            [round(lon), round(lat)]
                        })
                        .collect()
                })
                .collect();
            json!({"i": i, "id": lot.id.to_string(), "rings": rings,
                   "at": [round(lot.lonlat.0), round(lot.lonlat.1)]})
        })
        .collect();
    serde_json::to_vec(&list).unwrap_or_default()
}

impl Editor {
    /// Opens the KB, reads and prepares the footprints, binds 127.0.0.1 (`port` 0: a free
    /// one) and makes the session token.
    pub(crate) fn bind(opts: &EditOptions) -> Result<Editor, EditorError> {
        let draft = Draft::open(&opts.kb)?;
        let footprints = match &opts.source {
            Some(s) => {
                let (site, name) = building::load_site(s)?;
                let json = footprints_json(&site);
                Some(Footprints { site, name, json })
            }
            None => None,
        };
        let listener =
            TcpListener::bind(("127.0.0.1", opts.port)).map_err(|source| EditorError::Bind {
                port: opts.port,
                source,
            })?;
        let port = listener.local_addr().map_err(EditorError::Address)?.port();
        Ok(Editor {
            listener,
            port,
            token: new_token()?,
            draft: Arc::new(Mutex::new(draft)),
            footprints: Arc::new(footprints),
            seed: opts.seed,
            scratch: std::env::temp_dir(),
        })
    }

    /// The page's address with the token.
    pub(crate) fn url(&self) -> String {
        format!("http://127.0.0.1:{}/?token={}", self.port, self.token)
    }

    /// Serves until the process ends, with bounded connections, timeouts and workers
    /// (`conn`).
    pub(crate) fn serve(self) {
        let shared = Arc::new(Shared {
            port: self.port,
            token: self.token,
            draft: self.draft,
            footprints: self.footprints,
            seed: self.seed,
            scratch: self.scratch,
        });
        conn::serve(self.listener, move |req| shared.answer(req));
    }
}

/// What every worker shares.
struct Shared {
    port: u16,
    token: String,
    draft: Arc<Mutex<Draft>>,
    footprints: Arc<Option<Footprints>>,
    seed: u64,
    scratch: PathBuf,
}

/// Equal strings, compared in time independent of where they differ.
fn same_secret(a: &str, b: &str) -> bool {
    a.len() == b.len()
        && a.bytes()
            .zip(b.bytes())
            .fold(0u8, |acc, (x, y)| acc | (x ^ y))
            == 0
}

impl Shared {
    /// The answer to one request. A bug met while answering is a 500 with its message, never
    /// a closed connection (the draft's lock recovers from it: `Shared::lock`).
    fn answer(&self, req: &Request) -> Response {
        std::panic::catch_unwind(std::panic::AssertUnwindSafe(|| self.respond(req))).unwrap_or_else(
            |p| {
                let what = p
                    .downcast_ref::<&str>()
                    .map(|s| s.to_string())
                    .or_else(|| p.downcast_ref::<String>().cloned())
                    .unwrap_or_default();
                Response::error(500, &format!("internal error: {what}"))
            },
        )
    }

    /// The refusal of a request that is not this session's, or `None`.
    fn refusal(&self, req: &Request) -> Option<Response> {
        let hosts = [
            format!("127.0.0.1:{}", self.port),
            format!("localhost:{}", self.port),
        ];
        match req.header("host") {
            Some(h) if hosts.iter().any(|x| x == h) => {}
            Some(h) => {
                return Some(Response::error(
                    403,
                    &format!(
                        "refused: Host {h:?} is not this editor's (127.0.0.1:{})",
                        self.port
                    ),
                ))
            }
            None => return Some(Response::error(403, "refused: no Host header")),
        }
        if let Some(o) = req.header("origin") {
            if !hosts.iter().any(|h| o == format!("http://{h}")) {
                return Some(Response::error(
                    403,
                    &format!("refused: Origin {o:?} is not this editor's"),
                ));
            }
        }
        let token = if req.path.starts_with("/api/") {
            req.header("x-citygen-token")
        } else {
            req.query("token")
        };
        match token {
            Some(t) if same_secret(t, &self.token) => None,
            Some(_) => Some(Response::error(403, "refused: wrong session token")),
            None => Some(Response::error(
                403,
                "refused: no session token (open the address citygen kb edit printed)",
            )),
        }
    }

    fn respond(&self, req: &Request) -> Response {
        if let Some(r) = self.refusal(req) {
            return r;
        }
        let page = |ty: &'static str, body: &str| Response {
            status: 200,
            content_type: ty,
            body: body.replace("__TOKEN__", &self.token).into_bytes(),
        };
        match (req.method.as_str(), req.path.as_str()) {
            ("GET", "/") => page("text/html; charset=utf-8", INDEX_HTML),
            ("GET", "/app.js") => page("text/javascript; charset=utf-8", APP_JS),
            ("GET", "/viewer.js") => page("text/javascript; charset=utf-8", VIEWER_JS),
            ("GET", "/style.css") => page("text/css; charset=utf-8", STYLE_CSS),
            ("GET", "/api/state") => Response::json(200, &self.lock().state()),
            ("GET", "/api/footprints") => Response {
                status: 200,
                content_type: "application/json",
                body: match self.footprints.as_ref() {
                    Some(f) => f.json.clone(),
                    None => b"[]".to_vec(),
                },
            },
            ("GET", "/api/building") => self.building(req),
            ("GET", "/api/preview") => self.preview(req),
            ("POST", "/api/edit") => self.edit(req),
            ("POST", "/api/save") => match self.lock().save() {
                Ok(()) => Response::json(200, &json!({"saved": true})),
                Err(e) => Response::error(409, &e.to_string()),
            },
            ("POST", "/api/ruleset") => self.ruleset(req),
            (_, "/" | "/app.js" | "/viewer.js" | "/style.css")
            | (_, "/api/state")
            | (_, "/api/footprints")
            | (_, "/api/building")
            | (_, "/api/preview")
            | (_, "/api/edit")
            | (_, "/api/save")
            | (_, "/api/ruleset") => {
                Response::error(405, &format!("{} is not allowed here", req.method))
            }
            _ => Response::error(404, &format!("no page {}", req.path)),
        }
    }

    fn lock(&self) -> std::sync::MutexGuard<'_, Draft> {
        // A thread that panicked while holding the lock left a draft that was either changed
        // whole or not at all (edits replace it in one assignment).
        self.draft.lock().unwrap_or_else(|p| p.into_inner())
    }

    fn json_body<T: serde::de::DeserializeOwned>(req: &Request) -> Result<T, Response> {
        if !req
            .header("content-type")
            .is_some_and(|t| t.starts_with("application/json"))
        {
            return Err(Response::error(415, "send the body as application/json"));
        }
        serde_json::from_slice(&req.body)
            .map_err(|e| Response::error(400, &format!("the request's JSON: {e}")))
    }

    fn edit(&self, req: &Request) -> Response {
        let e: Edit = match Self::json_body(req) {
            Ok(e) => e,
            Err(r) => return r,
        };
        let mut d = self.lock();
        match d.apply(e) {
            Ok(()) => Response::json(200, &d.state()),
            Err(msg) => Response::error(422, &msg.to_string()),
        }
    }

    fn ruleset(&self, req: &Request) -> Response {
        #[derive(serde::Deserialize)]
        #[serde(deny_unknown_fields)]
        struct Body {
            file: String,
            text: String,
        }
        let b: Body = match Self::json_body(req) {
            Ok(b) => b,
            Err(r) => return r,
        };
        match self.lock().write_ruleset(&b.file, &b.text) {
            Ok(_) => Response::json(200, &json!({"written": b.file})),
            Err(e) => Response::error(422, &e.to_string()),
        }
    }

    /// The lot a request names (`i=` index or `id=way/123`).
    fn lot_index(&self, req: &Request) -> Result<(usize, &Footprints), Response> {
        let Some(f) = self.footprints.as_ref() else {
            return Err(Response::error(
                404,
                "the editor was started without --osm or --shp",
            ));
        };
        let found = if let Some(i) = req.query("i") {
            i.parse::<usize>().ok().filter(|i| *i < f.site.lots.len())
        } else if let Some(id) = req.query("id") {
            f.site.lots.iter().position(|l| l.id.to_string() == id)
        } else {
            None
        };
        found
            .map(|i| (i, f))
            .ok_or_else(|| Response::error(404, "no such building (give i= or id=)"))
    }

    fn building(&self, req: &Request) -> Response {
        let (i, f) = match self.lot_index(req) {
            Ok(x) => x,
            Err(r) => return r,
        };
        let kb = match self.lock().parsed() {
            Ok(kb) => kb,
            Err(e) => return Response::error(500, &e.to_string()),
        };
        let Some(e) = building::explain_lot(&kb, &f.site, i, self.seed) else {
            return Response::error(404, "no such building");
        };
        Response::json(
            200,
            &json!({
                "i": i,
                "id": f.site.lots[i].id.to_string(),
                "lon": e.lon, "lat": e.lat,
                "zone": kb.zone_path(e.zone),
                "boundary": e.boundary,
                "chain": e.chain.iter().map(|c| c.path.clone()).collect::<Vec<_>>(),
                "appearance": e.style.appearance_label,
                "candidates": e.candidates.iter().map(|c| json!({
                    "label": c.label, "proba": c.proba, "weight": c.weight,
                    "eligible": c.eligible, "chosen": c.chosen,
                })).collect::<Vec<_>>(),
                "values": e.values.iter().map(|v| json!({
                    "attribute": v.attribute, "value": v.value, "from": v.from,
                })).collect::<Vec<_>>(),
                "overrides": e.overrides,
                "inferred": e.inferred,
                "notes": e.notes,
                "provenance": e.provenance,
            }),
        )
    }

    fn preview(&self, req: &Request) -> Response {
        let (i, f) = match self.lot_index(req) {
            Ok(x) => x,
            Err(r) => return r,
        };
        let lod = match req.query("lod").unwrap_or("2") {
            "2" => Lod::Lod2,
            "3" => Lod::Lod3,
            other => return Response::error(400, &format!("lod {other:?}: 2 or 3")),
        };
        let kb = match self.lock().parsed() {
            Ok(kb) => kb,
            Err(e) => return Response::error(500, &e.to_string()),
        };
        match building::derive_glb(kb, &f.site, i, lod, self.seed, &f.name, &self.scratch) {
            Ok(bytes) => Response {
                status: 200,
                content_type: "model/gltf-binary",
                body: bytes,
            },
            Err(e) => Response::error(422, &e.to_string()),
        }
    }
}

/// Binds the editor, prints its address (one line on stdout, flushed) and serves until the
/// process is stopped.
pub fn run(opts: &EditOptions) -> Result<(), EditorError> {
    use std::io::Write;
    let editor = Editor::bind(opts)?;
    let mut out = std::io::stdout();
    let _ = writeln!(out, "{}", editor.url());
    let _ = out.flush();
    editor.serve();
    Ok(())
}
