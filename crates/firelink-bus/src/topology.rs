//! Cable topology and the self-ID numbering it produces.
//!
//! Nodes have numbered ports; a cable joins one port of one node to one port
//! of another. 1394 cable buses are trees: a cable that would close a loop is
//! refused. After a bus reset the tree is rooted at the root node, and the
//! self-ID process numbers the nodes in *topology order*: a post-order walk
//! from the root that visits each node's children in port order (a parent
//! grants self-ID to its lowest-numbered child port first, and a node sends
//! its own self-ID after all its children). Leaves far from the root get the
//! low IDs and the root gets the highest.
//!
//! For a daisy chain PC - a - b - c with the PC as root, c gets 0, b 1, a 2
//! and the PC 3.

use firelink_wire::packet::Speed;
use firelink_wire::phy::PortStatus;

use crate::error::BusError;

/// Largest number of nodes on one bus (physical IDs 0..=62).
pub const MAX_NODES: usize = 63;

#[derive(Clone, Copy, Debug, PartialEq, Eq)]
struct PortLink {
    node: usize,
    port: u8,
}

/// The cables between nodes.
#[derive(Clone, Debug, Default)]
pub struct Topology {
    ports: Vec<Vec<Option<PortLink>>>,
}

impl Topology {
    /// Add a node with `ports` ports; returns its index.
    pub fn add_node(&mut self, ports: u8) -> usize {
        self.ports.push(vec![None; usize::from(ports.max(1))]);
        self.ports.len() - 1
    }

    /// Number of nodes (connected or not).
    pub fn len(&self) -> usize {
        self.ports.len()
    }

    /// Whether there are no nodes.
    pub fn is_empty(&self) -> bool {
        self.ports.is_empty()
    }

    fn port_count(&self, node: usize) -> Result<usize, BusError> {
        self.ports
            .get(node)
            .map(Vec::len)
            .ok_or(BusError::NoSuchNode(node))
    }

    fn free_port(&self, node: usize) -> Result<u8, BusError> {
        let ports = self.ports.get(node).ok_or(BusError::NoSuchNode(node))?;
        ports
            .iter()
            .position(Option::is_none)
            .map(|p| p as u8)
            .ok_or(BusError::NoFreePort(node))
    }

    /// Join the lowest free port of `a` to the lowest free port of `b`.
    ///
    /// # Errors
    /// [`BusError::NoSuchNode`], [`BusError::NoFreePort`],
    /// [`BusError::Loop`] if `a` and `b` are already on one bus (or equal),
    /// [`BusError::TooManyNodes`] if the joined bus would exceed 63 nodes.
    pub fn connect(&mut self, a: usize, b: usize) -> Result<(u8, u8), BusError> {
        let pa = self.free_port(a)?;
        let pb = self.free_port(b)?;
        self.connect_ports(a, pa, b, pb)?;
        Ok((pa, pb))
    }

    /// Join port `pa` of `a` to port `pb` of `b`.
    ///
    /// # Errors
    /// As [`connect`](Self::connect), and [`BusError::PortInUse`] /
    /// [`BusError::NoSuchPort`].
    pub fn connect_ports(&mut self, a: usize, pa: u8, b: usize, pb: u8) -> Result<(), BusError> {
        for (n, p) in [(a, pa), (b, pb)] {
            let count = self.port_count(n)?;
            if usize::from(p) >= count {
                return Err(BusError::NoSuchPort { node: n, port: p });
            }
            if self.ports[n][usize::from(p)].is_some() {
                return Err(BusError::PortInUse { node: n, port: p });
            }
        }
        let comp_a = self.component(a);
        if a == b || comp_a.contains(&b) {
            return Err(BusError::Loop { a, b });
        }
        let total = comp_a.len() + self.component(b).len();
        if total > MAX_NODES {
            return Err(BusError::TooManyNodes(total));
        }
        self.ports[a][usize::from(pa)] = Some(PortLink { node: b, port: pb });
        self.ports[b][usize::from(pb)] = Some(PortLink { node: a, port: pa });
        Ok(())
    }

    /// Remove the cable between `a` and `b`.
    ///
    /// # Errors
    /// [`BusError::NotConnected`] if there is none.
    pub fn disconnect(&mut self, a: usize, b: usize) -> Result<(), BusError> {
        let mut found = false;
        for (x, y) in [(a, b), (b, a)] {
            if let Some(ports) = self.ports.get_mut(x) {
                for slot in ports.iter_mut() {
                    if slot.is_some_and(|l| l.node == y) {
                        *slot = None;
                        found = true;
                    }
                }
            }
        }
        if found {
            Ok(())
        } else {
            Err(BusError::NotConnected { a, b })
        }
    }

    /// The ports joined by the cable between `a` and `b`, as (port of a,
    /// port of b).
    pub fn link_between(&self, a: usize, b: usize) -> Option<(u8, u8)> {
        let ports = self.ports.get(a)?;
        ports
            .iter()
            .enumerate()
            .find_map(|(pa, l)| l.filter(|l| l.node == b).map(|l| (pa as u8, l.port)))
    }

    /// Whether a cable joins `a` and `b`.
    pub fn are_connected(&self, a: usize, b: usize) -> bool {
        self.ports
            .get(a)
            .is_some_and(|ports| ports.iter().any(|l| l.is_some_and(|l| l.node == b)))
    }

    /// Neighbours of `node` in port order.
    pub fn neighbours(&self, node: usize) -> impl Iterator<Item = usize> + '_ {
        self.ports
            .get(node)
            .into_iter()
            .flatten()
            .filter_map(|l| l.map(|l| l.node))
    }

    /// Every node reachable from `start` (including it), in index order.
    pub fn component(&self, start: usize) -> Vec<usize> {
        if start >= self.ports.len() {
            return Vec::new();
        }
        let mut seen = vec![false; self.ports.len()];
        let mut stack = vec![start];
        seen[start] = true;
        while let Some(n) = stack.pop() {
            for m in self.neighbours(n) {
                if !seen[m] {
                    seen[m] = true;
                    stack.push(m);
                }
            }
        }
        (0..self.ports.len()).filter(|&i| seen[i]).collect()
    }

    /// Run tree identification and self-ID numbering from `root`.
    /// `speeds[i]` is node i's maximum speed.
    pub fn tree(&self, root: usize, speeds: &[Speed]) -> Tree {
        let n = self.ports.len();
        let mut tree = Tree {
            root,
            by_phy: Vec::new(),
            phy_of: vec![None; n],
            parent: vec![None; n],
            depth: vec![0; n],
            port_status: vec![Vec::new(); n],
            hops: Vec::new(),
            path_speed: Vec::new(),
            by_distance: Vec::new(),
            eccentricity: Vec::new(),
        };
        if root >= n {
            return tree;
        }
        // Post-order walk, children in port order.
        enum Step {
            Enter(usize, Option<usize>, u32),
            Exit(usize),
        }
        let mut stack = vec![Step::Enter(root, None, 0)];
        while let Some(step) = stack.pop() {
            match step {
                Step::Enter(node, parent, depth) => {
                    tree.parent[node] = parent;
                    tree.depth[node] = depth;
                    stack.push(Step::Exit(node));
                    let children: Vec<usize> = self
                        .neighbours(node)
                        .filter(|&c| Some(c) != parent)
                        .collect();
                    for &c in children.iter().rev() {
                        stack.push(Step::Enter(c, Some(node), depth + 1));
                    }
                }
                Step::Exit(node) => {
                    tree.phy_of[node] = Some(tree.by_phy.len() as u8);
                    tree.by_phy.push(node);
                }
            }
        }
        for &node in &tree.by_phy {
            tree.port_status[node] = self.ports[node]
                .iter()
                .map(|l| match l {
                    None => PortStatus::NotConnected,
                    Some(l) if Some(l.node) == tree.parent[node] => PortStatus::Parent,
                    Some(_) => PortStatus::Child,
                })
                .collect();
        }
        // All-pairs hops and path speeds, indexed by physical ID.
        let m = tree.by_phy.len();
        tree.hops = vec![0; m * m];
        tree.path_speed = vec![Speed::S100; m * m];
        for (src_phy, &src) in tree.by_phy.iter().enumerate() {
            let mut dist = vec![u8::MAX; n];
            let mut slow = vec![Speed::S400; n];
            dist[src] = 0;
            slow[src] = speeds.get(src).copied().unwrap_or(Speed::S100);
            let mut queue = std::collections::VecDeque::from([src]);
            while let Some(x) = queue.pop_front() {
                for y in self.neighbours(x) {
                    if dist[y] == u8::MAX {
                        dist[y] = dist[x].saturating_add(1);
                        slow[y] = slow[x].min(speeds.get(y).copied().unwrap_or(Speed::S100));
                        queue.push_back(y);
                    }
                }
            }
            for (dst_phy, &dst) in tree.by_phy.iter().enumerate() {
                tree.hops[src_phy * m + dst_phy] = dist[dst];
                tree.path_speed[src_phy * m + dst_phy] = slow[dst];
            }
        }
        // Each physical ID's listeners, nearest first: a packet's
        // arrivals, listed in this order, come out in time order.
        tree.by_distance = (0..m)
            .flat_map(|src| {
                let mut order: Vec<u8> = (0..m).map(|d| d as u8).collect();
                order.sort_by_key(|&d| (tree.hops[src * m + usize::from(d)], d));
                order
            })
            .collect();
        tree.eccentricity = (0..m)
            .map(|a| {
                tree.hops[a * m..(a + 1) * m]
                    .iter()
                    .copied()
                    .max()
                    .unwrap_or(0)
            })
            .collect();
        tree
    }
}

/// The result of tree identification and self-ID for one root.
#[derive(Clone, Debug, Default)]
pub struct Tree {
    /// Node index of the root.
    pub root: usize,
    /// Node index of each physical ID (index = physical ID).
    pub by_phy: Vec<usize>,
    /// Physical ID of each node index (`None`: not on this bus).
    pub phy_of: Vec<Option<u8>>,
    /// Parent of each node (towards the root).
    pub parent: Vec<Option<usize>>,
    /// Hops from each node to the root.
    pub depth: Vec<u32>,
    /// Port states of each node on the bus, for self-ID packets.
    pub port_status: Vec<Vec<PortStatus>>,
    hops: Vec<u8>,
    path_speed: Vec<Speed>,
    /// Row `a`: every physical ID by (hops from `a`, ID).
    by_distance: Vec<u8>,
    /// The farthest any node is from each physical ID, in hops.
    eccentricity: Vec<u8>,
}

impl Tree {
    /// Nodes on the bus.
    pub fn node_count(&self) -> usize {
        self.by_phy.len()
    }

    /// Hops between two physical IDs (0 for unknown IDs).
    pub fn hops(&self, a: u8, b: u8) -> u32 {
        let m = self.by_phy.len();
        let (a, b) = (usize::from(a), usize::from(b));
        if a >= m || b >= m {
            return 0;
        }
        u32::from(self.hops[a * m + b])
    }

    /// Every physical ID as a packet from `a` reaches it: nearest first
    /// (ties by ID) when `nearest_first`, else by ID; by ID for an unknown
    /// `a`.
    pub fn listeners(&self, a: u8, nearest_first: bool) -> impl Iterator<Item = u8> + '_ {
        let m = self.by_phy.len();
        let row = self.nearest_first(a).filter(|_| nearest_first);
        let by_id = row.is_none();
        row.into_iter()
            .flatten()
            .copied()
            .chain((0..m).map(|d| d as u8).filter(move |_| by_id))
    }

    /// Every physical ID by (hops from `a`, ID): the order a packet from
    /// `a` reaches them (`None` for an unknown `a`).
    pub fn nearest_first(&self, a: u8) -> Option<&[u8]> {
        let m = self.by_phy.len();
        let a = usize::from(a);
        if a >= m {
            return None;
        }
        self.by_distance.get(a * m..(a + 1) * m)
    }

    /// Fastest speed every PHY on the path between two physical IDs supports.
    pub fn path_speed(&self, a: u8, b: u8) -> Speed {
        let m = self.by_phy.len();
        let (a, b) = (usize::from(a), usize::from(b));
        if a >= m || b >= m {
            return Speed::S100;
        }
        self.path_speed[a * m + b]
    }

    /// The farthest any node is from physical ID `a`, in hops.
    pub fn eccentricity(&self, a: u8) -> u32 {
        self.eccentricity
            .get(usize::from(a))
            .copied()
            .map_or(0, u32::from)
    }

    /// The largest hop count between any two nodes.
    pub fn diameter(&self) -> u32 {
        self.hops.iter().copied().max().map_or(0, u32::from)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn speeds(n: usize) -> Vec<Speed> {
        vec![Speed::S400; n]
    }

    /// A root with two chains, port 0 -> x0 -> x1 and port 1 -> y0: its
    /// tree and the nodes [root, x0, x1, y0].
    fn root_with_two_chains() -> (Tree, [usize; 4]) {
        let mut t = Topology::default();
        let root = t.add_node(3);
        let x0 = t.add_node(2);
        let x1 = t.add_node(2);
        let y0 = t.add_node(2);
        t.connect(root, x0).unwrap();
        t.connect(root, y0).unwrap();
        t.connect(x0, x1).unwrap();
        (t.tree(root, &speeds(4)), [root, x0, x1, y0])
    }

    #[test]
    fn daisy_chain_numbering() {
        let mut t = Topology::default();
        let pc = t.add_node(3);
        let a = t.add_node(2);
        let b = t.add_node(2);
        let c = t.add_node(2);
        t.connect(pc, a).unwrap();
        t.connect(a, b).unwrap();
        t.connect(b, c).unwrap();
        let tree = t.tree(pc, &speeds(4));
        assert_eq!(tree.by_phy, vec![c, b, a, pc]);
        assert_eq!(tree.phy_of[pc], Some(3));
        assert_eq!(tree.depth[c], 3);
        assert_eq!(tree.hops(0, 3), 3);
        assert_eq!(tree.hops(1, 2), 1);
        assert_eq!(tree.eccentricity(3), 3);
        assert_eq!(tree.diameter(), 3);
        assert_eq!(tree.port_status[a][0], PortStatus::Parent);
        assert_eq!(tree.port_status[a][1], PortStatus::Child);
    }

    #[test]
    fn listeners_come_nearest_first_with_ties_by_id() {
        // Physical IDs: x1 0, x0 1, y0 2, root 3.
        let (tree, _) = root_with_two_chains();
        let from = |a: u8, nearest: bool| tree.listeners(a, nearest).collect::<Vec<u8>>();
        // From y0 (2): itself, the root (1 hop), x0 (2), x1 (3).
        assert_eq!(from(2, true), vec![2, 3, 1, 0]);
        // From the root: itself, then x0 and y0 tie at 1 hop (by ID).
        assert_eq!(from(3, true), vec![3, 1, 2, 0]);
        assert_eq!(from(2, false), vec![0, 1, 2, 3]);
        assert_eq!(from(9, true), vec![0, 1, 2, 3]);
        for a in 0..4u8 {
            let hops: Vec<u32> = from(a, true).iter().map(|&b| tree.hops(a, b)).collect();
            assert!(hops.is_sorted(), "from {a}: {hops:?}");
        }
    }

    #[test]
    fn tree_numbering_visits_ports_in_order() {
        let (tree, [root, x0, x1, y0]) = root_with_two_chains();
        assert_eq!(tree.by_phy, vec![x1, x0, y0, root]);
        assert_eq!(tree.hops(0, 2), 3);
    }

    #[test]
    fn loops_ports_and_limits() {
        let mut t = Topology::default();
        let a = t.add_node(1);
        let b = t.add_node(2);
        let c = t.add_node(2);
        assert!(matches!(t.connect(a, a), Err(BusError::Loop { .. })));
        t.connect(a, b).unwrap();
        t.connect(b, c).unwrap();
        assert!(matches!(t.connect(a, c), Err(BusError::NoFreePort(_))));
        assert!(matches!(t.connect(c, b), Err(BusError::NoFreePort(_))));
        assert!(matches!(t.connect(9, a), Err(BusError::NoSuchNode(9))));
        t.disconnect(b, c).unwrap();
        assert!(t.disconnect(b, c).is_err());
        assert_eq!(t.component(a), vec![a, b]);
        // 64 nodes in a chain are refused at the 64th.
        let mut t = Topology::default();
        let nodes: Vec<usize> = (0..64).map(|_| t.add_node(2)).collect();
        for w in nodes.windows(2).take(62) {
            t.connect(w[0], w[1]).unwrap();
        }
        assert!(matches!(
            t.connect(nodes[62], nodes[63]),
            Err(BusError::TooManyNodes(64))
        ));
    }

    #[test]
    fn path_speed_is_the_slowest_phy() {
        let mut t = Topology::default();
        let a = t.add_node(2);
        let b = t.add_node(2);
        let c = t.add_node(2);
        t.connect(a, b).unwrap();
        t.connect(b, c).unwrap();
        let tree = t.tree(a, &[Speed::S400, Speed::S200, Speed::S400]);
        let (pa, pc) = (tree.phy_of[a].unwrap(), tree.phy_of[c].unwrap());
        assert_eq!(tree.path_speed(pa, pc), Speed::S200);
    }
}
