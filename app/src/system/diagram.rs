//! The diagram document: blocks (module instances) with their parameters and positions, and the
//! links between their ports. It knows nothing of egui: the canvas is an adapter over it
//! (`viewer.rs`), and every edit goes through the methods here, so the rules (unique names, one
//! source per input, matching data types) hold whatever the user interface does.
//!
//! The file format is the system XML that `armor check` accepts and `armor run` runs. Block
//! positions are not part of that format (its parser refuses unknown attributes), so they travel
//! in one XML comment at the end of the file, which every reader ignores:
//! `<!-- armor-studio layout: counter=120,80 checker=360,80 -->`.

use std::collections::{BTreeMap, BTreeSet};

use armor_model::system::{Endpoint, Link as SystemLink, ModuleInstance, ParamValue, SystemConfig};
use armor_module_api::describe::is_identifier;
use armor_module_api::xml::Located;

use crate::common::palette::Catalog;

mod groups;
pub use groups::{BORDER_TYPE_PREFIX, GROUP_TYPE_PREFIX, Group, border_id, border_of};

/// The comment that carries block positions.
const LAYOUT_TAG: &str = "armor-studio layout:";

/// A block's identity for the lifetime of the document: names can be edited, ids cannot.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash, PartialOrd, Ord)]
pub struct BlockId(pub u64);

/// One module instance on the canvas.
#[derive(Clone, Debug, PartialEq)]
pub struct Block {
    pub name: String,
    pub module_type: String,
    /// Values the user set; a parameter that is absent takes its default.
    pub params: BTreeMap<String, String>,
    /// Top-left corner on the canvas, in canvas units.
    pub pos: [f32; 2],
    /// What the file said about the instance that the editor does not show (host, restart
    /// policy, access lists): kept so that opening and saving a file loses nothing.
    pub instance: ModuleInstance,
}

/// One end of a link: a block and one of its ports, by name.
#[derive(Clone, Debug, PartialEq, Eq, Hash, PartialOrd, Ord)]
pub struct PortRef {
    pub block: BlockId,
    pub port: String,
}

/// A link from an output to an input.
#[derive(Clone, Debug, PartialEq, Eq, Hash, PartialOrd, Ord)]
pub struct Link {
    pub from: PortRef,
    pub to: PortRef,
    /// 0 for the input's source, 1, 2, … for its fallbacks (`fallback="N"` in the file),
    /// kept as the file says; the editor makes sources only.
    pub fallback: u32,
}

/// Which side of a block a pin is on.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub enum PinSide {
    Input,
    Output,
}

/// A pin the user can grab: a port of a block, with its side.
#[derive(Clone, Debug, PartialEq, Eq, Hash)]
pub struct Pin {
    pub side: PinSide,
    pub port: PortRef,
}

/// The document.
#[derive(Clone, Debug, PartialEq)]
pub struct Diagram {
    /// The system's name (`<system name=...>`).
    pub name: String,
    /// The system's host attribute, kept as it was read.
    pub host: Option<String>,
    /// The system's `<host>` declarations (the robot's other computers), kept as read.
    pub hosts: Vec<armor_model::HostDecl>,
    /// Links' `max_rate_hz`, by the input they feed (`module.input`), kept as read.
    pub link_rates: BTreeMap<String, f64>,
    /// Ordered by id, which is creation order: the file is written in that order.
    blocks: BTreeMap<BlockId, Block>,
    links: BTreeSet<Link>,
    /// Subsystems, by an id from the blocks' counter (see `groups.rs`).
    groups: BTreeMap<BlockId, Group>,
    next_id: u64,
}

impl Default for Diagram {
    fn default() -> Self {
        Diagram::new("system")
    }
}

/// Blocks and the links between them, as copied to the clipboard.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct Clip {
    blocks: Vec<(BlockId, Block)>,
    links: Vec<Link>,
}

impl Clip {
    pub fn is_empty(&self) -> bool {
        self.blocks.is_empty()
    }

    /// The clip as a system file of its own (what the studio puts on the system clipboard):
    /// another studio pastes it, a text editor shows it, `armor check` reads it.
    pub fn to_xml(&self) -> String {
        let mut diagram = Diagram::new("copied");
        diagram.paste(self, [0.0, 0.0]);
        diagram.to_xml()
    }

    /// The blocks and links of a system file (as [`Clip::to_xml`] writes); what is wrong with it
    /// (the parser's first problem, with its line) when it is none or has no module.
    pub fn from_xml(text: &str) -> Result<Clip, String> {
        let diagram = Diagram::from_xml(text).map_err(|problems| match problems.first() {
            Some(problem) => format!("the clipboard holds no system file ({problem})"),
            None => "the clipboard holds no system file".to_owned(),
        })?;
        let clip = diagram.copy(&diagram.blocks.keys().copied().collect());
        if clip.is_empty() {
            return Err("the clipboard's system has no module".to_owned());
        }
        Ok(clip)
    }
}

impl Diagram {
    pub fn new(name: &str) -> Diagram {
        Diagram {
            name: name.to_owned(),
            host: None,
            hosts: Vec::new(),
            link_rates: BTreeMap::new(),
            blocks: BTreeMap::new(),
            links: BTreeSet::new(),
            groups: BTreeMap::new(),
            next_id: 1,
        }
    }

    pub fn blocks(&self) -> impl Iterator<Item = (BlockId, &Block)> {
        self.blocks.iter().map(|(id, block)| (*id, block))
    }

    pub fn block(&self, id: BlockId) -> Option<&Block> {
        self.blocks.get(&id)
    }

    pub fn block_mut(&mut self, id: BlockId) -> Option<&mut Block> {
        self.blocks.get_mut(&id)
    }

    pub fn len(&self) -> usize {
        self.blocks.len()
    }

    pub fn is_empty(&self) -> bool {
        self.blocks.is_empty()
    }

    pub fn links(&self) -> impl Iterator<Item = &Link> {
        self.links.iter()
    }

    pub fn block_named(&self, name: &str) -> Option<BlockId> {
        self.blocks
            .iter()
            .find(|(_, block)| block.name == name)
            .map(|(id, _)| *id)
    }

    /// `base` if no block has that name, else `base_2`, `base_3`, ...
    pub fn unique_name(&self, base: &str) -> String {
        let taken: BTreeSet<&str> = self
            .blocks
            .values()
            .map(|b| b.name.as_str())
            .chain(self.groups.values().map(|g| g.name.as_str()))
            .collect();
        let base = if is_identifier(base) { base } else { "block" };
        if !taken.contains(base) {
            return base.to_owned();
        }
        // A copy of `sink_2` is `sink_3`, not `sink_2_2`.
        let base = match base.rsplit_once('_') {
            Some((stem, number))
                if !number.is_empty()
                    && number.bytes().all(|b| b.is_ascii_digit())
                    && is_identifier(stem) =>
            {
                stem
            }
            _ => base,
        };
        (2..)
            .map(|n| format!("{base}_{n}"))
            .find(|name| !taken.contains(name.as_str()))
            .unwrap_or_else(|| base.to_owned())
    }

    /// Adds an instance of `module_type` at `pos`, named after its type (made unique).
    pub fn add_block(&mut self, module_type: &str, pos: [f32; 2]) -> BlockId {
        let name = self.unique_name(module_type);
        self.insert(Block {
            instance: new_instance(&name, module_type),
            name,
            module_type: module_type.to_owned(),
            params: BTreeMap::new(),
            pos,
        })
    }

    fn insert(&mut self, block: Block) -> BlockId {
        let id = BlockId(self.next_id);
        self.next_id += 1;
        self.blocks.insert(id, block);
        id
    }

    /// Renames a block; the name must be an identifier no other block has.
    pub fn rename(&mut self, id: BlockId, name: &str) -> Result<(), String> {
        if self.is_group(id) {
            return self.rename_group(id, name);
        }
        self.check_name(name, Some(id))?;
        let block = self
            .blocks
            .get_mut(&id)
            .ok_or_else(|| "the block no longer exists".to_owned())?;
        block.name = name.to_owned();
        Ok(())
    }

    /// Sets a parameter (`Some`) or returns it to its default (`None`).
    pub fn set_param(&mut self, id: BlockId, name: &str, value: Option<String>) {
        if let Some(block) = self.blocks.get_mut(&id) {
            match value {
                Some(value) => block.params.insert(name.to_owned(), value),
                None => block.params.remove(name),
            };
        }
    }

    /// Moves a block, or a group's block.
    pub fn move_block(&mut self, id: BlockId, pos: [f32; 2]) {
        if let Some(block) = self.blocks.get_mut(&id) {
            block.pos = pos;
        } else if let Some(group) = self.groups.get_mut(&id) {
            group.pos = pos;
        }
    }

    /// Removes blocks (a group: every block in it) and every link that touches them.
    pub fn remove_blocks(&mut self, ids: &BTreeSet<BlockId>) {
        let ids = self.expand(ids);
        self.blocks.retain(|id, _| !ids.contains(id));
        self.links
            .retain(|link| !ids.contains(&link.from.block) && !ids.contains(&link.to.block));
        self.refresh_ports();
    }

    /// Removes the link from `link.from` to `link.to`, whatever its fallback rank (its ends
    /// may be a group's ports).
    pub fn remove_link(&mut self, link: &Link) -> bool {
        let link = &Link {
            from: self.resolve(&link.from),
            to: self.resolve(&link.to),
            fallback: link.fallback,
        };
        let before = self.links.len();
        self.links
            .retain(|kept| !(kept.from == link.from && kept.to == link.to));
        before != self.links.len()
    }

    /// Removes the links that end at an input; returns how many.
    pub fn disconnect_input(&mut self, input: &PortRef) -> usize {
        let input = &self.resolve(input);
        let before = self.links.len();
        self.links.retain(|link| &link.to != input);
        before - self.links.len()
    }

    /// Removes the links that start at an output; returns how many.
    pub fn disconnect_output(&mut self, output: &PortRef) -> usize {
        let output = &self.resolve(output);
        let before = self.links.len();
        self.links.retain(|link| &link.from != output);
        before - self.links.len()
    }

    /// The link feeding an input, if any.
    pub fn source_of(&self, input: &PortRef) -> Option<&Link> {
        self.links
            .iter()
            .find(|link| &link.to == input && link.fallback == 0)
    }

    /// Whether a wire dragged from `a` may end on `b` (in either order), and as which link; else
    /// why not, in words for the user.
    pub fn link_between(&self, catalog: &Catalog, a: &Pin, b: &Pin) -> Result<Link, String> {
        let a = &Pin {
            side: a.side,
            port: self.resolve(&a.port),
        };
        let b = &Pin {
            side: b.side,
            port: self.resolve(&b.port),
        };
        let (output, input) = match (a.side, b.side) {
            (PinSide::Output, PinSide::Input) => (&a.port, &b.port),
            (PinSide::Input, PinSide::Output) => (&b.port, &a.port),
            (PinSide::Input, PinSide::Input) => {
                return Err(format!(
                    "cannot link two inputs ({} and {}): a link goes from an output to an input",
                    self.port_label(&a.port),
                    self.port_label(&b.port)
                ));
            }
            (PinSide::Output, PinSide::Output) => {
                return Err(format!(
                    "cannot link two outputs ({} and {}): a link goes from an output to an input",
                    self.port_label(&a.port),
                    self.port_label(&b.port)
                ));
            }
        };
        let output_type = self.port_type(catalog, output, PinSide::Output)?;
        let input_type = self.port_type(catalog, input, PinSide::Input)?;
        if output_type != input_type {
            return Err(format!(
                "{} expects {input_type} but {} is {output_type}",
                self.port_label(input),
                self.port_label(output)
            ));
        }
        Ok(Link {
            from: output.clone(),
            to: input.clone(),
            fallback: 0,
        })
    }

    /// Adds a link checked by [`Diagram::link_between`]. An input has one source: a link into an
    /// input that already has one replaces it, and the replaced link is returned.
    pub fn connect(&mut self, catalog: &Catalog, a: &Pin, b: &Pin) -> Result<Option<Link>, String> {
        let link = self.link_between(catalog, a, b)?;
        if self.links.contains(&link) {
            return Ok(None);
        }
        let replaced = self.source_of(&link.to).cloned();
        if let Some(old) = &replaced {
            self.links.remove(old);
        }
        // The same output as a fallback of this input becomes its source.
        self.remove_link(&link);
        self.links.insert(link);
        self.refresh_ports();
        Ok(replaced)
    }

    /// Adds a link checked by [`Diagram::link_between`] as the input's next fallback source
    /// (rank one above its last), or as its source when it has none; returns the rank given.
    /// An output that already feeds the input, as its source or a fallback, is refused.
    pub fn connect_fallback(&mut self, catalog: &Catalog, a: &Pin, b: &Pin) -> Result<u32, String> {
        let mut link = self.link_between(catalog, a, b)?;
        let feeding: Vec<&Link> = self.links.iter().filter(|l| l.to == link.to).collect();
        if let Some(same) = feeding.iter().find(|l| l.from == link.from) {
            return Err(format!(
                "{} already feeds {}{}",
                self.port_label(&link.from),
                self.port_label(&link.to),
                if same.fallback > 0 {
                    format!(" (fallback {})", same.fallback)
                } else {
                    String::new()
                }
            ));
        }
        link.fallback = feeding.iter().map(|l| l.fallback + 1).max().unwrap_or(0);
        let rank = link.fallback;
        self.links.insert(link);
        Ok(rank)
    }

    /// `block.port`, as the user reads it.
    pub fn port_label(&self, port: &PortRef) -> String {
        let block = self
            .blocks
            .get(&port.block)
            .map_or("?", |block| block.name.as_str());
        format!("`{block}.{}`", port.port)
    }

    fn port_type<'c>(
        &self,
        catalog: &'c Catalog,
        port: &PortRef,
        side: PinSide,
    ) -> Result<&'c str, String> {
        let block = self
            .blocks
            .get(&port.block)
            .ok_or_else(|| "the block no longer exists".to_owned())?;
        let description = catalog.get(&block.module_type).ok_or_else(|| {
            format!(
                "module type `{}` of `{}` is unknown",
                block.module_type, block.name
            )
        })?;
        let spec = match side {
            PinSide::Input => description.input(&port.port),
            PinSide::Output => description.output(&port.port),
        };
        spec.map(|spec| spec.data_type.as_str()).ok_or_else(|| {
            format!(
                "`{}` has no {} called `{}`",
                block.name,
                if side == PinSide::Input {
                    "input"
                } else {
                    "output"
                },
                port.port
            )
        })
    }

    /// The required parameters of a block that have no value yet.
    pub fn missing_required(&self, catalog: &Catalog, id: BlockId) -> Vec<String> {
        let Some(block) = self.blocks.get(&id) else {
            return Vec::new();
        };
        let Some(description) = catalog.get(&block.module_type) else {
            return Vec::new();
        };
        description
            .params
            .iter()
            .filter(|spec| {
                spec.is_required()
                    && block
                        .params
                        .get(&spec.name)
                        .is_none_or(|v| v.trim().is_empty())
            })
            .map(|spec| spec.name.clone())
            .collect()
    }

    /// Every `block.param` still missing in the whole diagram, in block order.
    pub fn all_missing_required(&self, catalog: &Catalog) -> Vec<String> {
        self.blocks
            .iter()
            .flat_map(|(id, block)| {
                self.missing_required(catalog, *id)
                    .into_iter()
                    .map(move |param| format!("{}.{param}", block.name))
            })
            .collect()
    }

    /// A copy of the given blocks and of the links among them.
    pub fn copy(&self, ids: &BTreeSet<BlockId>) -> Clip {
        // A group stands for the blocks in it (its grouping is not copied).
        let ids = &self.expand(ids);
        Clip {
            blocks: ids
                .iter()
                .filter_map(|id| self.blocks.get(id).map(|block| (*id, block.clone())))
                .collect(),
            links: self
                .links
                .iter()
                .filter(|link| ids.contains(&link.from.block) && ids.contains(&link.to.block))
                .cloned()
                .collect(),
        }
    }

    /// Adds a copy of the clip, moved by `offset`, with fresh unique names; returns the new blocks.
    pub fn paste(&mut self, clip: &Clip, offset: [f32; 2]) -> Vec<BlockId> {
        let mut new_ids = BTreeMap::new();
        for (old_id, block) in &clip.blocks {
            let mut block = block.clone();
            block.name = self.unique_name(&block.name);
            block.instance.name.clone_from(&block.name);
            block.pos = [block.pos[0] + offset[0], block.pos[1] + offset[1]];
            new_ids.insert(*old_id, self.insert(block));
        }
        for link in &clip.links {
            if let (Some(from), Some(to)) =
                (new_ids.get(&link.from.block), new_ids.get(&link.to.block))
            {
                self.links.insert(Link {
                    from: PortRef {
                        block: *from,
                        port: link.from.port.clone(),
                    },
                    to: PortRef {
                        block: *to,
                        port: link.to.port.clone(),
                    },
                    fallback: link.fallback,
                });
            }
        }
        new_ids.into_values().collect()
    }

    /// The system configuration this diagram stands for.
    pub fn to_system(&self) -> SystemConfig {
        let modules = self
            .blocks
            .values()
            .map(|block| {
                let mut instance = block.instance.clone();
                instance.name.clone_from(&block.name);
                instance.module_type.clone_from(&block.module_type);
                instance.params = block
                    .params
                    .iter()
                    .map(|(name, value)| ParamValue {
                        name: name.clone(),
                        value: value.clone(),
                        pos: Default::default(),
                        value_pos: Default::default(),
                    })
                    .collect();
                instance
            })
            .collect();
        let endpoint = |port: &PortRef| {
            let block = self
                .blocks
                .get(&port.block)
                .map_or("", |block| block.name.as_str());
            Endpoint::new(block, &port.port)
        };
        let links = self
            .links
            .iter()
            .map(|link| SystemLink {
                from: endpoint(&link.from),
                to: endpoint(&link.to),
                fallback: link.fallback,
                pos: Default::default(),
                from_pos: Default::default(),
                to_pos: Default::default(),
                max_rate_hz: (link.fallback == 0)
                    .then(|| {
                        self.link_rates
                            .get(&endpoint(&link.to).to_string())
                            .copied()
                    })
                    .flatten(),
            })
            .collect();
        SystemConfig {
            name: self.name.clone(),
            host: self.host.clone(),
            hosts: self.hosts.clone(),
            modules,
            links,
            subsystems: self.subsystems(),
        }
    }

    /// The system XML, with the block positions in a trailing comment.
    pub fn to_xml(&self) -> String {
        let mut xml = self.to_system().to_xml();
        let layout: Vec<String> = self
            .blocks
            .values()
            .map(|block| (&block.name, block.pos))
            .map(|(name, pos)| (name.clone(), pos))
            .chain(self.groups.values().flat_map(|group| {
                let border = group
                    .border
                    .iter()
                    .zip([".in", ".out"])
                    .filter_map(|(pos, side)| {
                        pos.map(|pos| (format!("{}{side}", group.name), pos))
                    });
                std::iter::once((group.name.clone(), group.pos)).chain(border)
            }))
            .map(|(name, pos)| format!("{name}={:.0},{:.0}", pos[0], pos[1]))
            .collect();
        xml.push_str(&format!("<!-- {LAYOUT_TAG} {} -->\n", layout.join(" ")));
        xml
    }

    /// Lays the blocks out left to right by data flow, in layers (sources left, sinks right),
    /// with crossings reduced (see [`super::layout`]). Block sizes come from their ports: from
    /// `catalog` where it describes the block's type, else from the ports the links name.
    pub fn arrange(&mut self, catalog: Option<&Catalog>) {
        // Each level on its own: the top, and the inside of each group.
        let levels: Vec<Option<BlockId>> = std::iter::once(None)
            .chain(self.groups.keys().copied().map(Some))
            .collect();
        for level in levels {
            let ids: Vec<BlockId> = self
                .blocks
                .keys()
                .chain(self.groups.keys())
                .copied()
                .filter(|id| self.level_of(*id) == level)
                .collect();
            let index: BTreeMap<BlockId, usize> =
                ids.iter().enumerate().map(|(i, id)| (*id, i)).collect();
            let sizes: Vec<[f32; 2]> = ids
                .iter()
                .map(|id| match self.groups.get(id) {
                    Some(group) => [
                        (group.name.len() as f32 * 9.0 + 160.0).max(220.0),
                        60.0 + group.ports.len().max(1) as f32 * 26.0,
                    ],
                    None => self.estimated_size(*id, catalog),
                })
                .collect();
            let edges: Vec<(usize, usize)> = self
                .links
                .iter()
                .filter_map(|link| {
                    let from = self.shown_at(link.from.block, level)?;
                    let to = self.shown_at(link.to.block, level)?;
                    Some((*index.get(&from)?, *index.get(&to)?))
                })
                .collect();
            let positions = crate::system::layout::layered(&sizes, &edges, [40.0, 40.0]);
            for (id, pos) in ids.into_iter().zip(positions) {
                self.move_block(id, [pos[0].round(), pos[1].round()]);
            }
        }
    }

    /// About the size the canvas draws a block at: a header, a row per port, as wide as the
    /// longest input and output labels (`name: Type`) side by side, or the header's name and
    /// type. Without the type's description, the ports the links name stand for its ports and
    /// each type is guessed six letters long (`Twist`, `Pose2D`).
    fn estimated_size(&self, id: BlockId, catalog: Option<&Catalog>) -> [f32; 2] {
        let Some(block) = self.blocks.get(&id) else {
            return [200.0, 100.0];
        };
        let label = |name: &str, data_type: &str| name.len() + data_type.len() + 2;
        let (inputs, outputs): (Vec<usize>, Vec<usize>) =
            match catalog.and_then(|catalog| catalog.get(&block.module_type)) {
                Some(description) => (
                    description
                        .inputs
                        .iter()
                        .map(|port| label(&port.name, &port.data_type))
                        .collect(),
                    description
                        .outputs
                        .iter()
                        .map(|port| label(&port.name, &port.data_type))
                        .collect(),
                ),
                None => {
                    let named = |side: fn(&Link) -> &PortRef| {
                        self.links
                            .iter()
                            .map(side)
                            .filter(|port| port.block == id)
                            .map(|port| port.port.as_str())
                            .collect::<BTreeSet<_>>()
                            .into_iter()
                            .map(|name| label(name, "Type__"))
                            .collect::<Vec<_>>()
                    };
                    (named(|link| &link.to), named(|link| &link.from))
                }
            };
        let longest = |labels: &[usize]| labels.iter().copied().max().unwrap_or(0);
        let header = block.name.len() + block.module_type.len() + 4;
        let chars = (longest(&inputs) + longest(&outputs)).max(header) as f32;
        let rows = inputs.len().max(outputs.len()).max(1) as f32;
        [chars * 7.5 + 80.0, 60.0 + rows * 26.0]
    }

    /// Reads a system file; a file without saved positions is laid out in layers by data flow
    /// ([`Diagram::arrange`]), and a block missing from saved positions (a module added to the
    /// file by hand) goes in a grid below the blocks that have one, never over them.
    pub fn from_xml(text: &str) -> Result<Diagram, Vec<Located>> {
        let system = SystemConfig::parse(text)?;
        let layout = read_layout(text);
        let unlaid = layout.is_empty();
        let mut diagram = Diagram::new(&system.name);
        diagram.host.clone_from(&system.host);
        diagram.hosts.clone_from(&system.hosts);
        diagram.link_rates = system
            .links
            .iter()
            .filter_map(|link| Some((link.to.to_string(), link.max_rate_hz?)))
            .collect();
        let mut by_name = BTreeMap::new();
        // The grid of blocks without a position starts a row below the lowest one placed.
        let below_placed = layout
            .values()
            .map(|[_, y]| *y + GRID_ROW)
            .fold(0.0_f32, f32::max);
        let mut unplaced = 0;
        for (index, module) in system.modules.iter().enumerate() {
            let pos = match layout.get(module.name.as_str()) {
                Some(pos) => *pos,
                None if unlaid => grid_position(index),
                None => {
                    let [x, y] = grid_position(unplaced);
                    unplaced += 1;
                    [x, y + below_placed]
                }
            };
            let id = diagram.insert(Block {
                name: module.name.clone(),
                module_type: module.module_type.clone(),
                params: module
                    .params
                    .iter()
                    .map(|param| (param.name.clone(), param.value.clone()))
                    .collect(),
                pos,
                instance: extras(module),
            });
            by_name.entry(module.name.clone()).or_insert(id);
        }
        // A link naming an unknown module is kept out of the diagram: `check` reports it when the
        // file is checked, and there is no block to draw it to.
        for link in &system.links {
            if let (Some(from), Some(to)) =
                (by_name.get(&link.from.module), by_name.get(&link.to.module))
            {
                diagram.links.insert(Link {
                    from: PortRef {
                        block: *from,
                        port: link.from.port.clone(),
                    },
                    to: PortRef {
                        block: *to,
                        port: link.to.port.clone(),
                    },
                    fallback: link.fallback,
                });
            }
        }
        diagram.add_subsystems(&system.subsystems, None, &by_name, &layout);
        diagram.refresh_ports();
        if unlaid {
            diagram.arrange(None);
        }
        Ok(diagram)
    }
}

fn new_instance(name: &str, module_type: &str) -> ModuleInstance {
    // The one place that knows the defaults of an instance is the system parser: ask it.
    let text =
        format!("<system name=\"s\"><module name=\"{name}\" type=\"{module_type}\"/></system>");
    SystemConfig::parse(&text)
        .ok()
        .and_then(|system| system.modules.first().map(extras))
        .unwrap_or_else(|| ModuleInstance {
            name: name.to_owned(),
            module_type: module_type.to_owned(),
            host: None,
            restart: Default::default(),
            activation: Default::default(),
            params: Vec::new(),
            may_publish: None,
            may_subscribe: None,
            pos: Default::default(),
            type_pos: Default::default(),
        })
}

/// What a block keeps of the instance it was read from: what the editor does not show (host,
/// restart policy, access lists), without the positions in the file it came from or the
/// parameters (the block holds those), so that equal documents compare equal.
fn extras(module: &ModuleInstance) -> ModuleInstance {
    ModuleInstance {
        params: Vec::new(),
        pos: Default::default(),
        type_pos: Default::default(),
        ..module.clone()
    }
}

/// The height of a row of [`grid_position`]'s grid.
const GRID_ROW: f32 = 200.0;

/// Where the `index`-th block of a file without layout goes: rows of six.
pub fn grid_position(index: usize) -> [f32; 2] {
    let column = (index % 6) as f32;
    let row = (index / 6) as f32;
    [40.0 + column * 360.0, 40.0 + row * GRID_ROW]
}

fn read_layout(text: &str) -> BTreeMap<&str, [f32; 2]> {
    let mut layout = BTreeMap::new();
    let Some(start) = text.find(LAYOUT_TAG) else {
        return layout;
    };
    let rest = &text[start + LAYOUT_TAG.len()..];
    let rest = rest.split("-->").next().unwrap_or("");
    for entry in rest.split_whitespace() {
        let Some((name, xy)) = entry.split_once('=') else {
            continue;
        };
        let Some((x, y)) = xy.split_once(',') else {
            continue;
        };
        if let (Ok(x), Ok(y)) = (x.parse::<f32>(), y.parse::<f32>())
            && x.is_finite()
            && y.is_finite()
        {
            layout.insert(name, [x, y]);
        }
    }
    layout
}

#[cfg(test)]
#[allow(clippy::unwrap_used)]
mod tests {
    use super::*;
    use armor_module_api::ModuleDescription;
    use armor_module_api::describe::{ParamSpec, ParamType, PortSpec};

    fn catalog() -> Catalog {
        let mut counter = ModuleDescription::new("counter", "counts");
        counter.outputs.push(port("count", "Counter"));
        counter
            .params
            .push(ParamSpec::new("period_secs", ParamType::Float, "period").unit("s"));
        let mut checker = ModuleDescription::new("checker", "checks");
        checker.inputs.push(port("input", "Counter"));
        checker.inputs.push(port("other", "Blob"));
        [counter, checker]
            .into_iter()
            .map(|d| (d.module_type.clone(), d))
            .collect()
    }

    fn port(name: &str, data_type: &str) -> PortSpec {
        PortSpec {
            name: name.into(),
            data_type: data_type.into(),
            doc: String::new(),
        }
    }

    fn pin(side: PinSide, block: BlockId, port: &str) -> Pin {
        Pin {
            side,
            port: PortRef {
                block,
                port: port.into(),
            },
        }
    }

    #[test]
    fn names_are_unique_and_checked() {
        let mut diagram = Diagram::default();
        let a = diagram.add_block("counter", [0.0, 0.0]);
        let b = diagram.add_block("counter", [0.0, 0.0]);
        assert_eq!(diagram.block(b).map(|b| b.name.as_str()), Some("counter_2"));
        assert!(diagram.rename(b, "counter").is_err());
        assert!(diagram.rename(b, "2bad").is_err());
        assert!(diagram.rename(a, "counter").is_ok());
        assert!(diagram.rename(b, "fast").is_ok());
    }

    #[test]
    fn links_are_checked_and_one_source_per_input() {
        let catalog = catalog();
        let mut diagram = Diagram::default();
        let a = diagram.add_block("counter", [0.0, 0.0]);
        let a2 = diagram.add_block("counter", [0.0, 0.0]);
        let b = diagram.add_block("checker", [0.0, 0.0]);
        let out = pin(PinSide::Output, a, "count");
        let input = pin(PinSide::Input, b, "input");
        assert_eq!(diagram.connect(&catalog, &input, &out), Ok(None));
        let err = diagram
            .connect(&catalog, &out, &pin(PinSide::Input, b, "other"))
            .unwrap_err();
        assert_eq!(
            err,
            "`checker.other` expects Blob but `counter.count` is Counter"
        );
        let err = diagram
            .connect(&catalog, &input, &pin(PinSide::Input, b, "other"))
            .unwrap_err();
        assert!(err.contains("two inputs"), "{err}");
        let replaced = diagram.connect(&catalog, &pin(PinSide::Output, a2, "count"), &input);
        assert!(matches!(replaced, Ok(Some(_))));
        assert_eq!(diagram.links().count(), 1);
    }

    #[test]
    fn xml_round_trip_keeps_positions_params_and_links() {
        let catalog = catalog();
        let mut diagram = Diagram::new("demo");
        let a = diagram.add_block("counter", [10.0, 20.0]);
        let b = diagram.add_block("checker", [300.0, 40.0]);
        diagram.set_param(a, "period_secs", Some("0.5".into()));
        diagram
            .connect(
                &catalog,
                &pin(PinSide::Output, a, "count"),
                &pin(PinSide::Input, b, "input"),
            )
            .unwrap();
        let xml = diagram.to_xml();
        assert!(SystemConfig::parse(&xml).is_ok(), "{xml}");
        let again = Diagram::from_xml(&xml).unwrap();
        assert_eq!(again.to_xml(), xml);
        assert_eq!(again.block(BlockId(2)).map(|b| b.pos), Some([300.0, 40.0]));
    }

    #[test]
    fn fallback_links_are_kept_and_a_new_wire_replaces_only_the_source() {
        let catalog = catalog();
        let xml = "<system name=\"s\">\n<module name=\"a\" type=\"counter\"/>\n<module name=\"b\" type=\"counter\"/>\n<module name=\"k\" type=\"checker\"/>\n<link from=\"a.count\" to=\"k.input\"/>\n<link from=\"b.count\" to=\"k.input\" fallback=\"1\"/>\n</system>";
        let mut diagram = Diagram::from_xml(xml).unwrap();
        let written = diagram.to_xml();
        assert!(
            written.contains(r#"<link from="b.count" to="k.input" fallback="1"/>"#),
            "{written}"
        );
        let system = SystemConfig::parse(&written).unwrap();
        assert_eq!(system.links.len(), 2);
        // A wire from `b` into the input becomes its source; the fallback from `b` goes with
        // the old source, replaced.
        let [a, b, k] = ["a", "b", "k"].map(|name| diagram.block_named(name).unwrap());
        let replaced = diagram
            .connect(
                &catalog,
                &pin(PinSide::Output, b, "count"),
                &pin(PinSide::Input, k, "input"),
            )
            .unwrap();
        assert_eq!(replaced.map(|link| link.from.block), Some(a));
        assert!(
            diagram.remove_link(&Link {
                from: PortRef {
                    block: b,
                    port: "count".into()
                },
                to: PortRef {
                    block: k,
                    port: "input".into()
                },
                fallback: 7,
            }),
            "removed whatever its rank"
        );
        assert_eq!(diagram.links().count(), 0);
    }

    #[test]
    fn a_wire_dropped_as_a_fallback_takes_the_next_rank_and_reads_back() {
        let catalog = catalog();
        let xml = "<system name=\"s\">\n<module name=\"a\" type=\"counter\"/>\n<module name=\"b\" type=\"counter\"/>\n<module name=\"c\" type=\"counter\"/>\n<module name=\"k\" type=\"checker\"/>\n</system>";
        let mut diagram = Diagram::from_xml(xml).unwrap();
        let [a, b, c, k] = ["a", "b", "c", "k"].map(|name| diagram.block_named(name).unwrap());
        let input = pin(PinSide::Input, k, "input");
        let count = |block| pin(PinSide::Output, block, "count");
        // Into an input with no source, it is the source.
        assert_eq!(diagram.connect_fallback(&catalog, &count(a), &input), Ok(0));
        assert_eq!(diagram.connect_fallback(&catalog, &input, &count(b)), Ok(1));
        assert_eq!(diagram.connect_fallback(&catalog, &count(c), &input), Ok(2));
        let again = diagram.connect_fallback(&catalog, &count(b), &input);
        assert_eq!(
            again,
            Err("`b.count` already feeds `k.input` (fallback 1)".to_owned())
        );
        let written = diagram.to_xml();
        for line in [
            r#"<link from="a.count" to="k.input"/>"#,
            r#"<link from="b.count" to="k.input" fallback="1"/>"#,
            r#"<link from="c.count" to="k.input" fallback="2"/>"#,
        ] {
            assert!(written.contains(line), "{written}");
        }
        assert!(SystemConfig::parse(&written).is_ok(), "{written}");
    }

    #[test]
    fn copy_paste_renames_and_keeps_inner_links() {
        let catalog = catalog();
        let mut diagram = Diagram::default();
        let a = diagram.add_block("counter", [0.0, 0.0]);
        let b = diagram.add_block("checker", [0.0, 0.0]);
        diagram
            .connect(
                &catalog,
                &pin(PinSide::Output, a, "count"),
                &pin(PinSide::Input, b, "input"),
            )
            .unwrap();
        let clip = diagram.copy(&[a, b].into_iter().collect());
        let new = diagram.paste(&clip, [20.0, 20.0]);
        assert_eq!(new.len(), 2);
        assert_eq!(diagram.links().count(), 2);
        assert!(diagram.block_named("counter_2").is_some());
    }

    #[test]
    fn missing_required_parameters_are_named() {
        let catalog = catalog();
        let mut diagram = Diagram::default();
        let a = diagram.add_block("counter", [0.0, 0.0]);
        assert_eq!(
            diagram.all_missing_required(&catalog),
            ["counter.period_secs"]
        );
        diagram.set_param(a, "period_secs", Some("1".into()));
        assert!(diagram.all_missing_required(&catalog).is_empty());
    }
}
