use echogym_protocol::services::{Access, control_service};
use echogym_protocol::{IpcLocation, ServiceNames};
use iceoryx2::prelude::*;
fn main() {
    let a: Vec<String> = std::env::args().collect();
    let loc = IpcLocation { prefix: a[1].clone(), root: a[2].clone().into() };
    let mut config = loc.iceoryx_config().unwrap();
    config.global.node.cleanup_dead_nodes_on_creation = false;
    config.global.node.cleanup_dead_nodes_on_destruction = false;
    config.global.service.cleanup_dead_nodes_on_open = false;
    let node = NodeBuilder::new().config(&config).create::<ipc_threadsafe::Service>().unwrap();
    let names = ServiceNames::new(&a[3]).unwrap();
    let svc = control_service(&node, &names.control(), Access::Open).unwrap();
    let dc = svc.dynamic_config();
    println!("servers {} clients {}", dc.number_of_servers(), dc.number_of_clients());
    dc.list_servers(|s| { println!("server {:?} node {:?}", s.server_id, s.node_id); CallbackProgression::Continue });
    let _ = Node::<ipc_threadsafe::Service>::list(&config, |state| {
        match &state {
            NodeState::Alive(v) => { use iceoryx2::node::NodeView; println!("alive {:?} {:?}", v.id(), v.details().as_ref().map(|d| d.name().to_string())) }
            NodeState::Dead(v) => { use iceoryx2::node::NodeView; println!("DEAD {:?} {:?}", v.id(), v.details().as_ref().map(|d| d.name().to_string())) }
            other => println!("other {other:?}"),
        }
        CallbackProgression::Continue
    });
}
