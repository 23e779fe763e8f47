//! The ROS 2 parameter services of a forcemap node (`rcl_interfaces`: list_parameters,
//! get_parameters, get_parameter_types, describe_parameters, set_parameters,
//! set_parameters_atomically), so that `ros2 param list/get/describe/set` work on it.
//!
//! Served here rather than by ros2-client's own parameter store: that store describes every
//! parameter as "(description missing, not implemented)" and writable, and it applies a set
//! through a synchronous callback on the spinner's task. A live set of the identifier must run
//! in the node's own loop (it re-solves the state machine's equations and publishes theta), so
//! a set request is sent to that loop over a channel and answered once the loop has applied or
//! refused it: `successful: true` means the new theta is already out.

use std::collections::BTreeMap;
use std::sync::{Arc, Mutex};

use ros2_client::parameters::{ParameterValue, raw};
use ros2_client::rcl_interfaces::{
    DescribeParametersRequest, DescribeParametersResponse, GetParameterTypesRequest,
    GetParameterTypesResponse, GetParametersRequest, GetParametersResponse, ListParametersRequest,
    ListParametersResponse, ListParametersResult, SetParametersAtomicallyResponse,
    SetParametersRequest, SetParametersResponse,
};
use ros2_client::{Message, Name, Node, QosProfile, Server, ServiceMapping, ServiceTypeName};
use tokio::sync::{mpsc, oneshot};

use forcemap_io::params::{ParamValue, Params};

/// One declared parameter.
#[derive(Debug, Clone, PartialEq)]
pub struct Declared {
    pub value: ParamValue,
    pub description: String,
    /// Fixed at start: a set is refused.
    pub read_only: bool,
}

/// A node's declared parameters, shared by the service tasks and the node's loop.
#[derive(Debug, Clone, Default)]
pub struct ParameterTable {
    entries: Arc<Mutex<BTreeMap<String, Declared>>>,
}

impl ParameterTable {
    /// Every parameter the node was started with, read-only, described by where it came from
    /// (for the nodes whose parameters cannot change while they run).
    pub fn read_only(params: &Params) -> ParameterTable {
        let t = ParameterTable::default();
        for (name, value) in params.iter() {
            let from = params.origin(name).unwrap_or("the command line");
            t.declare(
                name,
                value.clone(),
                &format!("set at start (from {from}); fixed while the node runs"),
                true,
            );
        }
        t
    }

    pub fn declare(&self, name: &str, value: ParamValue, description: &str, read_only: bool) {
        self.lock().insert(
            name.to_string(),
            Declared {
                value,
                description: description.to_string(),
                read_only,
            },
        );
    }

    pub fn get(&self, name: &str) -> Option<Declared> {
        self.lock().get(name).cloned()
    }

    /// Stores a value the node has applied.
    pub fn store(&self, name: &str, value: ParamValue) {
        if let Some(d) = self.lock().get_mut(name) {
            d.value = value;
        }
    }

    pub fn names(&self) -> Vec<String> {
        self.lock().keys().cloned().collect()
    }

    fn lock(&self) -> std::sync::MutexGuard<'_, BTreeMap<String, Declared>> {
        // A panicked holder cannot leave the map half-written (every change is one insert).
        self.entries
            .lock()
            .unwrap_or_else(std::sync::PoisonError::into_inner)
    }

    /// Why `name` cannot be set here (undeclared or read-only), checked before the node's loop
    /// sees the request.
    fn refusal(&self, name: &str) -> Option<String> {
        match self.get(name) {
            None => Some(format!("parameter '{name}' is not declared on this node")),
            Some(d) if d.read_only => Some(format!(
                "parameter '{name}' is read-only: it is fixed at start (restart the node with -p {name}:=VALUE)"
            )),
            Some(_) => None,
        }
    }
}

/// A set of writable parameters for the node's loop to apply; answer it with
/// [`SetRequest::reply`].
#[derive(Debug)]
pub struct SetRequest {
    pub params: Vec<(String, ParamValue)>,
    /// All or nothing (`set_parameters_atomically`); otherwise each on its own.
    pub atomically: bool,
    reply: oneshot::Sender<Vec<Result<(), String>>>,
}

impl SetRequest {
    /// One result per parameter (one in all when atomic).
    pub fn reply(self, results: Vec<Result<(), String>>) {
        let _ = self.reply.send(results);
    }
}

/// The rcl_interfaces value of a parameter, or why it has none forcemap can take.
pub fn from_wire(v: raw::ParameterValue) -> Result<Option<ParamValue>, String> {
    Ok(Some(match ParameterValue::from(v) {
        ParameterValue::NotSet => return Ok(None),
        ParameterValue::Boolean(b) => ParamValue::Bool(b),
        ParameterValue::Integer(i) => ParamValue::Integer(i),
        ParameterValue::Double(d) => ParamValue::Double(d),
        ParameterValue::String(s) => ParamValue::String(s),
        ParameterValue::BooleanArray(a) => ParamValue::BoolArray(a),
        ParameterValue::IntegerArray(a) => ParamValue::IntegerArray(a),
        ParameterValue::DoubleArray(a) => ParamValue::DoubleArray(a),
        ParameterValue::StringArray(a) => ParamValue::StringArray(a),
        ParameterValue::ByteArray(_) => return Err("byte arrays are no forcemap parameter".into()),
    }))
}

pub fn to_wire(v: &ParamValue) -> raw::ParameterValue {
    let v = match v.clone() {
        ParamValue::Bool(b) => ParameterValue::Boolean(b),
        ParamValue::Integer(i) => ParameterValue::Integer(i),
        ParamValue::Double(d) => ParameterValue::Double(d),
        ParamValue::String(s) => ParameterValue::String(s),
        ParamValue::BoolArray(a) => ParameterValue::BooleanArray(a),
        ParamValue::IntegerArray(a) => ParameterValue::IntegerArray(a),
        ParamValue::DoubleArray(a) => ParameterValue::DoubleArray(a),
        ParamValue::StringArray(a) => ParameterValue::StringArray(a),
        // `[]` has no element type; ROS tools show it as a string array.
        ParamValue::EmptyArray => ParameterValue::StringArray(Vec::new()),
    };
    v.into()
}

fn describe(name: &str, d: Option<Declared>) -> raw::ParameterDescriptor {
    let (r#type, description, read_only) = match d {
        Some(d) => (to_wire(&d.value).ptype, d.description, d.read_only),
        None => (
            raw::ParameterType::NOT_SET,
            "not declared on this node".to_string(),
            true,
        ),
    };
    raw::ParameterDescriptor {
        name: name.to_string(),
        r#type,
        description,
        additional_constraints: String::new(),
        read_only,
        dynamic_typing: false,
        floating_point_range: Vec::new(),
        integer_range: Vec::new(),
    }
}

/// `ListParameters` as rclcpp answers it: no prefixes, every name within `depth` levels of
/// `.` (0: any); otherwise the names equal to or under a prefix.
fn list(names: Vec<String>, prefixes: &[String], depth: u64) -> ListParametersResult {
    let within = |s: &str| depth == 0 || (s.matches('.').count() as u64) < depth;
    let mut out = ListParametersResult {
        names: Vec::new(),
        prefixes: Vec::new(),
    };
    for name in names {
        let listed = if prefixes.is_empty() {
            within(&name)
        } else {
            prefixes.iter().any(|p| {
                name == *p
                    || name
                        .strip_prefix(p.as_str())
                        .and_then(|r| r.strip_prefix('.'))
                        .is_some_and(&within)
            })
        };
        if listed {
            if let Some((ns, _)) = name.rsplit_once('.')
                && !out.prefixes.iter().any(|p| p == ns)
            {
                out.prefixes.push(ns.to_string());
            }
            out.names.push(name);
        }
    }
    out
}

/// Checks a set request against the table and, for what passes, asks the node's loop
/// (`sets`; none: nothing is writable). One result per parameter, or one when atomic.
async fn set(
    table: &ParameterTable,
    sets: Option<&mpsc::UnboundedSender<SetRequest>>,
    request: Vec<raw::Parameter>,
    atomically: bool,
) -> Vec<Result<(), String>> {
    let mut checked: Vec<Result<(String, ParamValue), String>> = Vec::new();
    for p in request {
        let c = match (table.refusal(&p.name), from_wire(p.value)) {
            (Some(why), _) => Err(why),
            (None, Err(why)) => Err(format!("{}: {why}", p.name)),
            (None, Ok(None)) => Err(format!("parameter '{}' cannot be undeclared", p.name)),
            (None, Ok(Some(v))) => Ok((p.name, v)),
        };
        checked.push(c);
    }
    if atomically && let Some(Err(why)) = checked.iter().find(|c| c.is_err()) {
        return vec![Err(why.clone())];
    }
    let to_loop: Vec<(String, ParamValue)> =
        checked.iter().filter_map(|c| c.clone().ok()).collect();
    let mut from_loop = if to_loop.is_empty() {
        Vec::new()
    } else {
        let Some(sets) = sets else {
            // Unreachable with a table whose writable names have a loop to apply them.
            return vec![Err("this node applies no parameter sets".into()); checked.len()];
        };
        let (reply, answer) = oneshot::channel();
        let asked = sets.send(SetRequest {
            params: to_loop.clone(),
            atomically,
            reply,
        });
        match (asked, answer.await) {
            (Ok(()), Ok(results)) => results,
            _ => {
                vec![Err("the node is stopping".into()); if atomically { 1 } else { to_loop.len() }]
            }
        }
    }
    .into_iter();
    if atomically {
        return vec![from_loop.next().unwrap_or(Ok(()))];
    }
    checked
        .into_iter()
        .map(|c| match c {
            Err(why) => Err(why),
            Ok(_) => from_loop
                .next()
                .unwrap_or_else(|| Err("no answer from the node".into())),
        })
        .collect()
}

fn result(r: Result<(), String>) -> raw::SetParametersResult {
    match r {
        Ok(()) => raw::SetParametersResult {
            successful: true,
            reason: String::new(),
        },
        Err(reason) => raw::SetParametersResult {
            successful: false,
            reason,
        },
    }
}

/// Creates the six services of node `fq_name` and spawns their tasks. Sets of writable
/// parameters are sent into `sets`.
pub fn serve(
    node: &mut Node,
    fq_name: &str,
    table: ParameterTable,
    sets: Option<mpsc::UnboundedSender<SetRequest>>,
) -> anyhow::Result<()> {
    let list_server = server::<ListParametersRequest, ListParametersResponse>(
        node,
        fq_name,
        "list_parameters",
        "ListParameters",
    )?;
    let t = table.clone();
    respond(list_server, move |req| {
        let t = t.clone();
        async move {
            ListParametersResponse {
                result: list(t.names(), &req.prefixes, req.depth),
            }
        }
    });
    let get_server = server::<GetParametersRequest, GetParametersResponse>(
        node,
        fq_name,
        "get_parameters",
        "GetParameters",
    )?;
    let t = table.clone();
    respond(get_server, move |req| {
        let t = t.clone();
        async move {
            let values = req
                .names
                .iter()
                .map(|n| match t.get(n) {
                    Some(d) => to_wire(&d.value),
                    None => ParameterValue::NotSet.into(),
                })
                .collect();
            GetParametersResponse { values }
        }
    });
    let types_server = server::<GetParameterTypesRequest, GetParameterTypesResponse>(
        node,
        fq_name,
        "get_parameter_types",
        "GetParameterTypes",
    )?;
    let t = table.clone();
    respond(types_server, move |req| {
        let t = t.clone();
        async move {
            let values = req
                .names
                .iter()
                .map(|n| describe(n, t.get(n)).r#type)
                .collect();
            GetParameterTypesResponse { values }
        }
    });
    let describe_server = server::<DescribeParametersRequest, DescribeParametersResponse>(
        node,
        fq_name,
        "describe_parameters",
        "DescribeParameters",
    )?;
    let t = table.clone();
    respond(describe_server, move |req| {
        let t = t.clone();
        async move {
            let values = req.names.iter().map(|n| describe(n, t.get(n))).collect();
            DescribeParametersResponse { values }
        }
    });
    let set_server = server::<SetParametersRequest, SetParametersResponse>(
        node,
        fq_name,
        "set_parameters",
        "SetParameters",
    )?;
    let (t, s) = (table.clone(), sets.clone());
    respond(set_server, move |req| {
        let (t, s) = (t.clone(), s.clone());
        async move {
            let results = set(&t, s.as_ref(), req.parameter, false).await;
            SetParametersResponse {
                results: results.into_iter().map(result).collect(),
            }
        }
    });
    let atomic_server = server::<SetParametersRequest, SetParametersAtomicallyResponse>(
        node,
        fq_name,
        "set_parameters_atomically",
        "SetParametersAtomically",
    )?;
    respond(atomic_server, move |req| {
        let (t, s) = (table.clone(), sets.clone());
        async move {
            let r = set(&t, s.as_ref(), req.parameter, true).await;
            SetParametersAtomicallyResponse {
                result: result(r.into_iter().next().unwrap_or(Ok(()))),
            }
        }
    });
    Ok(())
}

fn server<Req, Resp>(
    node: &mut Node,
    fq_name: &str,
    service: &str,
    type_name: &str,
) -> anyhow::Result<Server<Req, Resp>>
where
    Req: Message + Clone + 'static,
    Resp: Message + 'static,
{
    // As ros2-client's own parameter servers: keep the last request, reliable.
    let qos =
        QosProfile::publisher_default().history(ros2_client::qos::History::KeepLast { depth: 1 });
    let name = Name::new(fq_name, service)
        .map_err(|e| anyhow::anyhow!("service name {fq_name}/{service}: {e:?}"))?;
    node.create_server::<Req, Resp>(
        ServiceMapping::Enhanced,
        &name,
        &ServiceTypeName::new("rcl_interfaces", type_name),
        qos.clone(),
        qos,
    )
    .map_err(|e| anyhow::anyhow!("the {service} service: {e:?}"))
}

/// Answers every request of `server` with `answer`, one at a time, for the node's life.
fn respond<Req, Resp, F, Fut>(server: Server<Req, Resp>, answer: F)
where
    Req: Message + Clone + Send + Sync + 'static,
    Resp: Message + Send + Sync + 'static,
    F: Fn(Req) -> Fut + Send + Sync + 'static,
    Fut: std::future::Future<Output = Resp> + Send,
    Server<Req, Resp>: Send,
{
    tokio::spawn(async move {
        loop {
            match server.async_receive_request().await {
                Ok((id, req)) => {
                    let resp = answer(req).await;
                    if let Err(e) = server.async_send_response(id, resp).await {
                        crate::log_line!("warning: answering a parameter request: {e:?}");
                    }
                }
                Err(e) => crate::log_line!("warning: receiving a parameter request: {e:?}"),
            }
        }
    });
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn listing_follows_prefixes_and_depth_as_rclcpp() {
        let names = || ["a", "b.c", "b.d.e", "model"].map(String::from).to_vec();
        assert_eq!(list(names(), &[], 0).names, names());
        assert_eq!(list(names(), &[], 1).names, vec!["a", "model"]);
        let r = list(names(), &["b".into()], 0);
        assert_eq!(r.names, vec!["b.c", "b.d.e"]);
        assert_eq!(r.prefixes, vec!["b", "b.d"]);
    }

    #[test]
    fn values_cross_the_wire_unchanged() {
        for v in [
            ParamValue::Bool(true),
            ParamValue::Integer(-3),
            ParamValue::Double(0.7),
            ParamValue::String("coulomb".into()),
            ParamValue::IntegerArray(vec![2, 3]),
            ParamValue::DoubleArray(vec![1.5]),
        ] {
            assert_eq!(from_wire(to_wire(&v)).unwrap(), Some(v));
        }
    }

    /// A node whose parameters cannot change declares what it was given, read-only, with
    /// where each value came from.
    #[test]
    fn a_node_declares_the_parameters_it_was_given_read_only() {
        let mut params = Params::new();
        params.set_from_override("bag:=bags/rig_40db").unwrap();
        params.set_with_origin("rate_factor", ParamValue::Double(0.0), "rig.params.yaml");
        let t = ParameterTable::read_only(&params);
        assert_eq!(t.names(), vec!["bag", "rate_factor"]);
        let d = t.get("rate_factor").unwrap();
        assert!(d.read_only);
        assert_eq!(d.value, ParamValue::Double(0.0));
        assert!(
            d.description.contains("rig.params.yaml"),
            "{}",
            d.description
        );
        let w = describe("bag", t.get("bag"));
        assert_eq!(w.r#type, raw::ParameterType::STRING);
        assert!(w.read_only);
        assert_eq!(describe("nope", None).r#type, raw::ParameterType::NOT_SET);
    }

    #[tokio::test]
    async fn read_only_and_undeclared_parameters_are_refused_by_name() {
        let t = ParameterTable::default();
        t.declare("mass_kg", ParamValue::Double(36.0), "mass", true);
        let p = |name: &str| raw::Parameter {
            name: name.into(),
            value: to_wire(&ParamValue::Double(1.0)),
        };
        let r = set(&t, None, vec![p("mass_kg"), p("nope")], false).await;
        assert!(
            r[0].as_ref()
                .unwrap_err()
                .contains("'mass_kg' is read-only")
        );
        assert!(
            r[1].as_ref()
                .unwrap_err()
                .contains("'nope' is not declared")
        );
        let r = set(&t, None, vec![p("mass_kg"), p("nope")], true).await;
        assert_eq!(r.len(), 1);
        assert!(r[0].as_ref().unwrap_err().contains("read-only"));
        assert_eq!(t.get("mass_kg").unwrap().value, ParamValue::Double(36.0));
    }
}
