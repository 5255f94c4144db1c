//! Subsystems in the diagram: blocks grouped under a name (the system file's `<subsystem>`),
//! drawn as one block whose pins are the ports it exposes, and opened to show its members.
//!
//! A group's id is a [`BlockId`] from the same counter as the blocks' (never a block's), so
//! that the editor's selection and the canvas hold blocks and groups alike. The canvas draws
//! one *level* at a time (the top, or the inside of a group): [`Diagram::at_level`] makes the
//! diagram of that level, each group in it a block of a made-up type (`subsystem NAME`, not an
//! identifier, so never a module type) whose inputs and outputs are the group's exposed ports;
//! links into a group end on its port. What the user does there comes back to the document
//! through [`Diagram::resolve`] (a group's port is the member's port it exposes).

use std::collections::{BTreeMap, BTreeSet};

use armor_model::system::{Endpoint, ExposedPort, Member, Subsystem};
use armor_module_api::ModuleDescription;
use armor_module_api::describe::{PortSpec, is_identifier};

use super::{Block, BlockId, Diagram, Link, PinSide, PortRef, new_instance};
use crate::common::palette::Catalog;

/// The prefix of a group's made-up module type in [`Diagram::at_level`]'s catalog.
pub const GROUP_TYPE_PREFIX: &str = "subsystem ";
/// The made-up type of the two blocks that stand, inside a group, for its border: its inputs
/// (`border in`, whose outputs they are) and its outputs (`border out`).
pub const BORDER_TYPE_PREFIX: &str = "border ";
/// Border blocks' ids: `BORDER_BASE + 2 × group` for the inputs, `+ 1` for the outputs.
const BORDER_BASE: u64 = 1 << 62;

/// The id of a group's border block: its inputs (`false`) or its outputs (`true`).
pub fn border_id(group: BlockId, outputs: bool) -> BlockId {
    BlockId(BORDER_BASE + 2 * group.0 + u64::from(outputs))
}

/// The group and side of a border block's id.
pub fn border_of(id: BlockId) -> Option<(BlockId, bool)> {
    let offset = id.0.checked_sub(BORDER_BASE)?;
    Some((BlockId(offset / 2), offset % 2 == 1))
}

/// A named group of blocks (and of groups).
#[derive(Clone, Debug, PartialEq)]
pub struct Group {
    pub name: String,
    /// The group it is in; `None` at the top.
    pub parent: Option<BlockId>,
    /// The blocks directly in it.
    pub members: BTreeSet<BlockId>,
    /// Its block's top-left corner, at its parent's level.
    pub pos: [f32; 2],
    /// The ports on its border: a name, and the member's port (at any depth) it stands for.
    pub ports: Vec<(String, PortRef)>,
    /// Where its inside draws the blocks of its border (inputs, outputs), once moved there.
    pub border: [Option<[f32; 2]>; 2],
}

impl Diagram {
    pub fn groups(&self) -> impl Iterator<Item = (BlockId, &Group)> {
        self.groups.iter().map(|(id, group)| (*id, group))
    }

    pub fn group(&self, id: BlockId) -> Option<&Group> {
        self.groups.get(&id)
    }

    pub fn is_group(&self, id: BlockId) -> bool {
        self.groups.contains_key(&id)
    }

    pub fn group_named(&self, name: &str) -> Option<BlockId> {
        self.groups
            .iter()
            .find(|(_, group)| group.name == name)
            .map(|(id, _)| *id)
    }

    /// The group a block or a group is directly in (`None`: the top).
    pub fn level_of(&self, id: BlockId) -> Option<BlockId> {
        if let Some(group) = self.groups.get(&id) {
            return group.parent;
        }
        self.groups
            .iter()
            .find(|(_, group)| group.members.contains(&id))
            .map(|(group, _)| *group)
    }

    /// The groups from the top down to `level` (empty at the top).
    pub fn path_to(&self, level: Option<BlockId>) -> Vec<BlockId> {
        let mut path = Vec::new();
        let mut at = level;
        while let Some(id) = at {
            if path.contains(&id) || !self.is_group(id) {
                break;
            }
            path.insert(0, id);
            at = self.level_of(id);
        }
        path
    }

    /// The item drawn at `level` that holds `id` (itself, or the group in `level` it is in);
    /// `None` when `id` is not inside `level`.
    pub fn shown_at(&self, id: BlockId, level: Option<BlockId>) -> Option<BlockId> {
        let mut item = id;
        loop {
            let parent = self.level_of(item);
            if parent == level {
                return Some(item);
            }
            item = parent?;
        }
    }

    /// Every block in a group, nested groups' too.
    pub fn blocks_in(&self, group: BlockId) -> BTreeSet<BlockId> {
        self.blocks
            .keys()
            .copied()
            .filter(|block| {
                let mut at = self.level_of(*block);
                while let Some(id) = at {
                    if id == group {
                        return true;
                    }
                    at = self.level_of(id);
                }
                false
            })
            .collect()
    }

    /// The blocks that `ids` stand for: blocks as they are, groups by every block in them.
    pub fn expand(&self, ids: &BTreeSet<BlockId>) -> BTreeSet<BlockId> {
        let mut blocks = BTreeSet::new();
        for id in ids {
            if self.is_group(*id) {
                blocks.extend(self.blocks_in(*id));
            } else if self.blocks.contains_key(id) {
                blocks.insert(*id);
            }
        }
        blocks
    }

    /// A port as the document has it: a group's port is the member's port it exposes.
    pub fn resolve(&self, port: &PortRef) -> PortRef {
        match self.groups.get(&port.block) {
            Some(group) => group
                .ports
                .iter()
                .find(|(name, _)| *name == port.port)
                .map_or_else(|| port.clone(), |(_, of)| of.clone()),
            None => port.clone(),
        }
    }

    /// Groups `items` (blocks and groups, all at one level) under a new group, named `name`
    /// or `subsystem`, `subsystem_2`, …; its ports are the members' ports that links join to
    /// blocks outside it. Returns the group's id.
    pub fn group_items(
        &mut self,
        items: &BTreeSet<BlockId>,
        name: Option<&str>,
    ) -> Result<BlockId, String> {
        let items: BTreeSet<BlockId> = items
            .iter()
            .copied()
            .filter(|id| self.blocks.contains_key(id) || self.is_group(*id))
            .collect();
        let Some(first) = items.first() else {
            return Err("select the blocks to group first".to_owned());
        };
        let level = self.level_of(*first);
        if items.iter().any(|id| self.level_of(*id) != level) {
            return Err("the blocks to group must be at one level".to_owned());
        }
        let name = match name {
            Some(name) => {
                self.check_name(name, None)?;
                name.to_owned()
            }
            None => self.unique_name("subsystem"),
        };
        let positions: Vec<[f32; 2]> = items.iter().filter_map(|id| self.item_pos(*id)).collect();
        let pos = [
            positions.iter().map(|p| p[0]).fold(f32::INFINITY, f32::min),
            positions.iter().map(|p| p[1]).fold(f32::INFINITY, f32::min),
        ];
        let id = BlockId(self.next_id);
        self.next_id += 1;
        if let Some(parent) = level.and_then(|level| self.groups.get_mut(&level)) {
            parent.members.retain(|member| !items.contains(member));
        }
        for item in &items {
            if let Some(group) = self.groups.get_mut(item) {
                group.parent = Some(id);
            }
        }
        self.groups.insert(
            id,
            Group {
                name,
                parent: level,
                members: items
                    .iter()
                    .copied()
                    .filter(|id| self.blocks.contains_key(id))
                    .collect(),
                pos: if pos[0].is_finite() {
                    pos
                } else {
                    [40.0, 40.0]
                },
                ports: Vec::new(),
                border: [None, None],
            },
        );
        self.refresh_ports();
        Ok(id)
    }

    /// Puts a group's members back at its level and removes it.
    pub fn ungroup(&mut self, id: BlockId) -> Result<(), String> {
        let group = self
            .groups
            .remove(&id)
            .ok_or_else(|| "that is not a subsystem".to_owned())?;
        if let Some(parent) = group.parent.and_then(|parent| self.groups.get_mut(&parent)) {
            parent.members.extend(group.members.iter().copied());
        }
        for inner in self.groups.values_mut() {
            if inner.parent == Some(id) {
                inner.parent = group.parent;
            }
        }
        Ok(())
    }

    /// Renames a group; the name must be an identifier no block or other group has.
    pub fn rename_group(&mut self, id: BlockId, name: &str) -> Result<(), String> {
        self.check_name(name, Some(id))?;
        let group = self
            .groups
            .get_mut(&id)
            .ok_or_else(|| "the subsystem no longer exists".to_owned())?;
        group.name = name.to_owned();
        Ok(())
    }

    pub(super) fn check_name(&self, name: &str, renamed: Option<BlockId>) -> Result<(), String> {
        if !is_identifier(name) {
            return Err(format!(
                "`{name}` is not a valid name: use letters, digits and `_`, starting with a letter"
            ));
        }
        let taken = self
            .block_named(name)
            .or_else(|| self.group_named(name))
            .is_some_and(|other| Some(other) != renamed);
        if taken {
            return Err(format!("another block is already called `{name}`"));
        }
        Ok(())
    }

    /// Puts blocks at the top into the group `level` (new blocks made while it is open).
    pub fn put_in(&mut self, level: Option<BlockId>, blocks: &[BlockId]) {
        let Some(group) = level.and_then(|level| self.groups.get_mut(&level)) else {
            return;
        };
        group.members.extend(blocks.iter().copied());
        self.refresh_ports();
    }

    fn item_pos(&self, id: BlockId) -> Option<[f32; 2]> {
        self.blocks
            .get(&id)
            .map(|block| block.pos)
            .or_else(|| self.groups.get(&id).map(|group| group.pos))
    }

    /// Keeps groups in step with the blocks: members and ports of removed blocks go, groups
    /// left empty go, and every member's port that a link joins to a block outside the group
    /// is exposed (under the port's name, or `block_port` when that is taken).
    pub(super) fn refresh_ports(&mut self) {
        let blocks = &self.blocks;
        for group in self.groups.values_mut() {
            group.members.retain(|member| blocks.contains_key(member));
            group.ports.retain(|(_, of)| blocks.contains_key(&of.block));
        }
        loop {
            let empty: Vec<BlockId> = self
                .groups
                .iter()
                .filter(|(id, group)| {
                    group.members.is_empty()
                        && !self.groups.values().any(|inner| inner.parent == Some(**id))
                })
                .map(|(id, _)| *id)
                .collect();
            if empty.is_empty() {
                break;
            }
            for id in empty {
                self.groups.remove(&id);
            }
        }
        let ids: Vec<BlockId> = self.groups.keys().copied().collect();
        for id in ids {
            let inside = self.blocks_in(id);
            let mut crossing: Vec<PortRef> = Vec::new();
            for link in &self.links {
                for (end, other) in [(&link.from, &link.to), (&link.to, &link.from)] {
                    if inside.contains(&end.block)
                        && !inside.contains(&other.block)
                        && !crossing.contains(end)
                    {
                        crossing.push(end.clone());
                    }
                }
            }
            let Some(group) = self.groups.get(&id) else {
                continue;
            };
            let mut ports = group.ports.clone();
            ports.retain(|(_, of)| inside.contains(&of.block));
            for end in crossing {
                if ports.iter().any(|(_, of)| *of == end) {
                    continue;
                }
                let block = self.blocks.get(&end.block).map_or("", |b| b.name.as_str());
                let name = if ports.iter().any(|(name, _)| *name == end.port) {
                    format!("{block}_{}", end.port)
                } else {
                    end.port.clone()
                };
                ports.push((name, end));
            }
            if let Some(group) = self.groups.get_mut(&id) {
                group.ports = ports;
            }
        }
    }

    /// Which side a block's port is on: from its type's description, else from the links.
    fn port_side(&self, catalog: &Catalog, port: &PortRef) -> Option<(PinSide, String)> {
        let block = self.blocks.get(&port.block)?;
        if let Some(description) = catalog.get(&block.module_type) {
            if let Some(spec) = description.input(&port.port) {
                return Some((PinSide::Input, spec.data_type.clone()));
            }
            if let Some(spec) = description.output(&port.port) {
                return Some((PinSide::Output, spec.data_type.clone()));
            }
        }
        if self.links.iter().any(|link| link.to == *port) {
            return Some((PinSide::Input, "?".to_owned()));
        }
        if self.links.iter().any(|link| link.from == *port) {
            return Some((PinSide::Output, "?".to_owned()));
        }
        None
    }

    /// The diagram drawn at `level` (the top, or inside a group), with the catalog it is drawn
    /// with: the blocks directly at that level as they are (same ids), each group at that level
    /// a block of the made-up type `subsystem NAME` whose inputs and outputs are its ports, and
    /// the links between what is drawn (a link into a group ends on the port that exposes its
    /// end; links to blocks outside `level` are not drawn).
    pub fn at_level(&self, level: Option<BlockId>, catalog: &Catalog) -> (Diagram, Catalog) {
        let mut view = Diagram::new(&self.name);
        view.host.clone_from(&self.host);
        view.next_id = self.next_id;
        let mut catalog = catalog.clone();
        for (id, block) in &self.blocks {
            if self.level_of(*id) == level {
                view.blocks.insert(*id, block.clone());
            }
        }
        for (id, group) in &self.groups {
            if group.parent != level {
                continue;
            }
            let module_type = format!("{GROUP_TYPE_PREFIX}{}", group.name);
            let mut description = ModuleDescription::new(
                &module_type,
                &format!("subsystem of {} modules", self.blocks_in(*id).len()),
            );
            for (name, of) in &group.ports {
                let Some((side, data_type)) = self.port_side(&catalog, of) else {
                    continue;
                };
                let spec = PortSpec {
                    name: name.clone(),
                    data_type,
                    doc: format!("{}.{}", self.block_name(of.block), of.port),
                };
                match side {
                    PinSide::Input => description.inputs.push(spec),
                    PinSide::Output => description.outputs.push(spec),
                }
            }
            catalog.insert(module_type.clone(), description);
            view.blocks.insert(
                *id,
                Block {
                    instance: new_instance(&group.name, "subsystem"),
                    name: group.name.clone(),
                    module_type,
                    params: BTreeMap::new(),
                    pos: group.pos,
                },
            );
        }
        if let Some(group) = level.and_then(|level| self.groups.get(&level).map(|g| (level, g))) {
            self.add_border(&mut view, &mut catalog, group);
        }
        let shown = |end: &PortRef| -> Option<PortRef> {
            let item = self.shown_at(end.block, level)?;
            if item == end.block {
                return Some(end.clone());
            }
            let group = self.groups.get(&item)?;
            let (name, _) = group.ports.iter().find(|(_, of)| of == end)?;
            Some(PortRef {
                block: item,
                port: name.clone(),
            })
        };
        for link in &self.links {
            if let (Some(from), Some(to)) = (shown(&link.from), shown(&link.to))
                && from.block != to.block
            {
                view.links.insert(Link {
                    from,
                    to,
                    fallback: link.fallback,
                });
            }
        }
        (view, catalog)
    }

    /// Inside `group`, the blocks of its border: its input ports as the outputs of one block on
    /// the left, its output ports as the inputs of one on the right, each linked to the
    /// members' ports they expose (and those blocks drawn where the user put them last).
    fn add_border(
        &self,
        view: &mut Diagram,
        catalog: &mut Catalog,
        (id, group): (BlockId, &Group),
    ) {
        // Beside what the level holds, a gap as wide as a column's wires away.
        let items: Vec<([f32; 2], f32)> = view
            .blocks
            .keys()
            .map(|item| {
                let width = if self.blocks.contains_key(item) {
                    self.estimated_size(*item, Some(catalog))[0]
                } else {
                    240.0
                };
                (view.blocks[item].pos, width)
            })
            .collect();
        let left = items
            .iter()
            .map(|(p, _)| p[0])
            .fold(f32::INFINITY, f32::min);
        let right = items
            .iter()
            .map(|(p, width)| p[0] + width)
            .fold(f32::NEG_INFINITY, f32::max);
        let top = items
            .iter()
            .map(|(p, _)| p[1])
            .fold(f32::INFINITY, f32::min);
        let (left, right, top) = if left.is_finite() {
            (left - 260.0, right + 40.0, top)
        } else {
            (40.0, 600.0, 40.0)
        };
        for (outputs, default) in [(false, [left, top]), (true, [right, top])] {
            let module_type = format!(
                "{BORDER_TYPE_PREFIX}{} {}",
                if outputs { "out" } else { "in" },
                group.name
            );
            let mut description = ModuleDescription::new(&module_type, "the subsystem's border");
            for (name, of) in &group.ports {
                let Some((side, data_type)) = self.port_side(catalog, of) else {
                    continue;
                };
                let spec = PortSpec {
                    name: name.clone(),
                    data_type,
                    doc: format!("{}.{}", self.block_name(of.block), of.port),
                };
                match (side, outputs) {
                    // An input of the group comes in through an output of its left border.
                    (PinSide::Input, false) => description.outputs.push(spec),
                    (PinSide::Output, true) => description.inputs.push(spec),
                    _ => {}
                }
            }
            if description.inputs.is_empty() && description.outputs.is_empty() {
                continue;
            }
            let border = border_id(id, outputs);
            catalog.insert(module_type.clone(), description);
            view.blocks.insert(
                border,
                Block {
                    instance: new_instance("border", "border"),
                    name: if outputs { "outputs" } else { "inputs" }.to_owned(),
                    module_type,
                    params: BTreeMap::new(),
                    pos: group.border[usize::from(outputs)].unwrap_or(default),
                },
            );
            // The links that cross the border, from (or to) its port.
            let inside = self.blocks_in(id);
            for link in &self.links {
                let (inner, outer) = if outputs {
                    (&link.from, &link.to)
                } else {
                    (&link.to, &link.from)
                };
                if !inside.contains(&inner.block) || inside.contains(&outer.block) {
                    continue;
                }
                let Some((name, _)) = group.ports.iter().find(|(_, of)| of == inner) else {
                    continue;
                };
                let Some(item) = self.shown_at(inner.block, Some(id)) else {
                    continue;
                };
                let inner_shown = if item == inner.block {
                    inner.clone()
                } else {
                    let Some((port, _)) = self
                        .groups
                        .get(&item)
                        .and_then(|g| g.ports.iter().find(|(_, of)| of == inner))
                    else {
                        continue;
                    };
                    PortRef {
                        block: item,
                        port: port.clone(),
                    }
                };
                let border_port = PortRef {
                    block: border,
                    port: name.clone(),
                };
                let (from, to) = if outputs {
                    (inner_shown, border_port)
                } else {
                    (border_port, inner_shown)
                };
                view.links.insert(Link {
                    from,
                    to,
                    fallback: link.fallback,
                });
            }
        }
    }

    /// Moves a border block of a group (where its inside draws it).
    pub fn move_border(&mut self, id: BlockId, pos: [f32; 2]) {
        if let Some((group, outputs)) = border_of(id)
            && let Some(group) = self.groups.get_mut(&group)
        {
            group.border[usize::from(outputs)] = Some(pos);
        }
    }

    fn block_name(&self, id: BlockId) -> &str {
        self.blocks
            .get(&id)
            .map_or("?", |block| block.name.as_str())
    }

    /// The groups as the system file's subsystems (nested under their parents).
    pub(super) fn subsystems(&self) -> Vec<Subsystem> {
        self.subsystems_in(None)
    }

    fn subsystems_in(&self, parent: Option<BlockId>) -> Vec<Subsystem> {
        self.groups
            .iter()
            .filter(|(_, group)| group.parent == parent)
            .map(|(id, group)| {
                let mut subsystem = Subsystem::new(&group.name);
                subsystem.members = group
                    .members
                    .iter()
                    .map(|member| Member {
                        module: self.block_name(*member).to_owned(),
                        pos: Default::default(),
                    })
                    .collect();
                subsystem.subsystems = self.subsystems_in(Some(*id));
                subsystem.ports = group
                    .ports
                    .iter()
                    .map(|(name, of)| ExposedPort {
                        name: name.clone(),
                        of: Endpoint::new(self.block_name(of.block), &of.port),
                        pos: Default::default(),
                        of_pos: Default::default(),
                    })
                    .collect();
                subsystem
            })
            .collect()
    }

    /// Adds the system file's subsystems as groups, the blocks found by name (`by_name`); a
    /// member that names no block is left out (`check` reports it).
    pub(super) fn add_subsystems(
        &mut self,
        subsystems: &[Subsystem],
        parent: Option<BlockId>,
        by_name: &BTreeMap<String, BlockId>,
        layout: &BTreeMap<&str, [f32; 2]>,
    ) {
        for subsystem in subsystems {
            let id = BlockId(self.next_id);
            self.next_id += 1;
            let members: BTreeSet<BlockId> = subsystem
                .members
                .iter()
                .filter_map(|member| by_name.get(&member.module).copied())
                .filter(|block| self.level_of(*block).is_none())
                .collect();
            let inner_pos = members
                .iter()
                .filter_map(|member| self.blocks.get(member).map(|block| block.pos))
                .next();
            let ports = subsystem
                .ports
                .iter()
                .filter_map(|port| {
                    Some((
                        port.name.clone(),
                        PortRef {
                            block: *by_name.get(&port.of.module)?,
                            port: port.of.port.clone(),
                        },
                    ))
                })
                .collect();
            self.groups.insert(
                id,
                Group {
                    name: subsystem.name.clone(),
                    parent,
                    members,
                    pos: layout
                        .get(subsystem.name.as_str())
                        .copied()
                        .or(inner_pos)
                        .unwrap_or([40.0, 40.0]),
                    ports,
                    border: [
                        layout
                            .get(format!("{}.in", subsystem.name).as_str())
                            .copied(),
                        layout
                            .get(format!("{}.out", subsystem.name).as_str())
                            .copied(),
                    ],
                },
            );
            self.add_subsystems(&subsystem.subsystems, Some(id), by_name, layout);
        }
    }
}

#[cfg(test)]
#[allow(clippy::unwrap_used)]
mod tests {
    use super::*;

    const NESTED: &str = r#"<system name="s">
  <module name="a" type="counter"/>
  <module name="b" type="checker"/>
  <module name="c" type="checker"/>
  <link from="a.count" to="b.input"/>
  <link from="a.count" to="c.input"/>
  <subsystem name="outer">
    <member module="b"/>
    <subsystem name="inner">
      <member module="c"/>
      <port name="input" of="c.input"/>
    </subsystem>
    <port name="input" of="b.input"/>
    <port name="c_input" of="c.input"/>
  </subsystem>
</system>
<!-- armor-studio layout: a=0,0 b=300,0 c=300,200 outer=300,0 inner=300,200 inner.in=10,20 -->
"#;

    fn catalog() -> Catalog {
        let mut counter = ModuleDescription::new("counter", "counts");
        counter.outputs.push(PortSpec {
            name: "count".into(),
            data_type: "Counter".into(),
            doc: String::new(),
        });
        let mut checker = ModuleDescription::new("checker", "checks");
        checker.inputs.push(PortSpec {
            name: "input".into(),
            data_type: "Counter".into(),
            doc: String::new(),
        });
        [counter, checker]
            .into_iter()
            .map(|d| (d.module_type.clone(), d))
            .collect()
    }

    #[test]
    fn nested_groups_are_read_written_and_read_back_equal() {
        let diagram = Diagram::from_xml(NESTED).unwrap();
        assert_eq!(diagram.groups().count(), 2);
        let inner = diagram.group_named("inner").unwrap();
        let outer = diagram.group_named("outer").unwrap();
        assert_eq!(diagram.level_of(inner), Some(outer));
        assert_eq!(diagram.group(inner).unwrap().border[0], Some([10.0, 20.0]));
        let written = diagram.to_xml();
        let again = Diagram::from_xml(&written).unwrap();
        assert_eq!(again, diagram, "{written}");
        assert_eq!(again.to_xml(), written);
    }

    #[test]
    fn each_level_draws_its_groups_as_blocks_with_their_ports() {
        let diagram = Diagram::from_xml(NESTED).unwrap();
        let catalog = catalog();
        // The top: a, and outer with its two input ports, each fed by a.
        let (top, top_catalog) = diagram.at_level(None, &catalog);
        let names: Vec<&str> = top.blocks().map(|(_, b)| b.name.as_str()).collect();
        assert_eq!(names, ["a", "outer"]);
        let outer = diagram.group_named("outer").unwrap();
        let outer_type = &top.block(outer).unwrap().module_type;
        let ports: Vec<&str> = top_catalog[outer_type]
            .inputs
            .iter()
            .map(|p| p.name.as_str())
            .collect();
        assert_eq!(ports, ["input", "c_input"]);
        let links: Vec<String> = top
            .links()
            .map(|l| format!("{}.{}>{}", l.from.block.0, l.from.port, l.to.port))
            .collect();
        assert_eq!(links.len(), 2, "{links:?}");
        // Inside outer: b, inner (a block), and the border's inputs linked to both.
        let (inside, _) = diagram.at_level(Some(outer), &catalog);
        let names: Vec<&str> = inside.blocks().map(|(_, b)| b.name.as_str()).collect();
        assert_eq!(names, ["b", "inner", "inputs"]);
        let inner = diagram.group_named("inner").unwrap();
        let into_inner = inside
            .links()
            .find(|l| l.to.block == inner)
            .expect("a link into inner's port");
        assert_eq!(into_inner.from.block, border_id(outer, false));
        assert_eq!(into_inner.from.port, "c_input");
        // A wire to a group's port is the member's port.
        assert_eq!(
            diagram.resolve(&PortRef {
                block: inner,
                port: "input".into()
            }),
            PortRef {
                block: diagram.block_named("c").unwrap(),
                port: "input".into()
            }
        );
    }

    #[test]
    fn grouping_a_group_nests_it_and_ungrouping_puts_it_back() {
        let mut diagram = Diagram::from_xml(NESTED).unwrap();
        let outer = diagram.group_named("outer").unwrap();
        let a = diagram.block_named("a").unwrap();
        // Items of two levels do not group.
        let inner = diagram.group_named("inner").unwrap();
        assert!(diagram.group_items(&[a, inner].into(), None).is_err());
        let top = diagram
            .group_items(&[a, outer].into(), Some("all"))
            .unwrap();
        assert_eq!(diagram.level_of(outer), Some(top));
        assert_eq!(diagram.level_of(a), Some(top));
        assert!(
            diagram.group(top).unwrap().ports.is_empty(),
            "nothing crosses it"
        );
        assert_eq!(
            diagram.group_items(&[a].into(), Some("b")),
            Err("another block is already called `b`".to_owned())
        );
        diagram.ungroup(top).unwrap();
        assert_eq!(diagram.level_of(outer), None);
        assert_eq!(diagram.level_of(a), None);
        // Removing the blocks of a group removes it, and its ports.
        diagram.remove_blocks(&[outer].into());
        assert_eq!(diagram.groups().count(), 0);
        assert_eq!(diagram.len(), 1);
    }
}
